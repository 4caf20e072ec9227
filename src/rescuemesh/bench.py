"""`rescuemesh bench`: the figures we track: real-time factor of the follow scenario and codec rate.

Owns: timing (wall clock) and the bench JSON. Must not know: scenario internals. Prints figures;
never fails on time: speed goals are read, not asserted.
"""

from __future__ import annotations

import json
import platform
import time
from pathlib import Path

from rescuemesh.protocol import MAX_CONTROL_FRAME_BYTES, MessageType
from rescuemesh.protocol.bench import codec_roundtrip_rate
from rescuemesh.protocol.codec import max_frame_bytes
from rescuemesh.scenarios import ScenarioOptions
from rescuemesh.scenarios.runner import run_scenario

RTF_GOAL = 20.0
CODEC_GOAL_FPS = 100_000


def run_bench(out: Path, *, seed: int = 0) -> int:
    outcome = run_scenario("follow", ScenarioOptions(seed=seed))
    result = outcome.result
    rate = codec_roundtrip_rate(1.0, time.perf_counter)
    figures = {
        "follow_real_time_factor": result["real_time_factor"],
        "follow_sim_time_s": result["sim_time_s"],
        "follow_wall_time_s": result["wall_time_s"],
        "follow_success": result["success"],
        "codec_frames_per_s": round(rate),
        "follow_max_frame_bytes": result["protocol"]["max_frame_bytes"],
        "largest_control_frame_bytes": {t.name: max_frame_bytes(t) for t in MessageType if t.value},
        "goals": {"real_time_factor": RTF_GOAL, "codec_frames_per_s": CODEC_GOAL_FPS},
        "machine": {"python": platform.python_version(), "processor": platform.machine()},
    }
    print(f"follow scenario : {figures['follow_sim_time_s']:.1f} s simulated in {figures['follow_wall_time_s']:.2f} s"
          f" -> {figures['follow_real_time_factor']}x real time (goal >= {RTF_GOAL:g}x)")
    print(f"codec           : {figures['codec_frames_per_s']:,} encode+decode frames/s (goal >= {CODEC_GOAL_FPS:,})")
    sizes = figures["largest_control_frame_bytes"]
    widest = max(sizes, key=sizes.get)
    print(f"largest frame   : {figures['follow_max_frame_bytes']} bytes in this run; "
          f"{sizes[widest]} bytes for any message ({widest}; budget {MAX_CONTROL_FRAME_BYTES})")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(figures, indent=2) + "\n")
    print(f"wrote {out}")
    return 0
