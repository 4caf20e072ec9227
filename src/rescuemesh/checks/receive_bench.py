"""What a robot's network stack costs per frame it has not heard before: a team's robots, one shared
sealer, every robot hearing every other's Heartbeat and PoseUpdate once (`python -m` this module).

Owns: the micro-benchmark of NetworkStack.receive on new frames. Must not know: radios, scenarios.
"""

from __future__ import annotations

import argparse
import time
from typing import Callable

from rescuemesh.mesh import MeshConfig, MeshNode, NetworkStack
from rescuemesh.mesh.security import FrameSealer
from rescuemesh.protocol import Endpoint, Pose

#: The sealer memory the simulated team has (runtime/assembly.TEAM_SEALER_MEMORY).
TEAM_MEMORY = 1024


def receive_cost(robots: int = 30, periods: int = 20, clock: Callable[[], float] = time.perf_counter,
                 remember: int = TEAM_MEMORY) -> tuple[float, int]:
    """(us per accepted frame, frames accepted): each period every robot sends a Heartbeat and a
    PoseUpdate to the next robot, and every robot hears each of those frames once (1 ms apart);
    only the receive() calls that accepted a frame are timed (relays are drained untimed)."""
    sealer = FrameSealer(bytes(range(16)), remember=remember)
    config = MeshConfig()
    stacks = [NetworkStack(Endpoint(a), MeshNode(a, config, sealer)) for a in range(1, robots + 1)]
    spent, accepted = 0.0, 0
    for period in range(periods):
        now = 1.0 + period
        frames = []
        for i, stack in enumerate(stacks):
            stack.endpoint.send_heartbeat(now)
            stack.endpoint.send_pose_update(stacks[(i + 1) % robots].address, Pose(1.0 * i, 2.0, 0.0, 0.5), now)
            frames += [t.data for t in stack.transmissions(now)]
        for k, data in enumerate(frames):
            at = now + 0.001 * k
            for stack in stacks:
                start = clock()
                ok = stack.receive(data, at, rssi_dbm=-60.0, relay_delay_s=0.01)
                if ok:
                    spent += clock() - start
                    accepted += 1
            for stack in stacks:
                stack.transmissions(at + 0.5)
                while stack.endpoint.next_event() is not None or stack.next_event() is not None:
                    pass
    return (1e6 * spent / accepted if accepted else float("nan")), accepted


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=30)
    parser.add_argument("--periods", type=int, default=20)
    args = parser.parse_args()
    us, accepted = receive_cost(args.robots, args.periods)
    print(f"{us:.2f} us per new frame accepted ({accepted} frames, {args.robots} robots)")


if __name__ == "__main__":
    main()
