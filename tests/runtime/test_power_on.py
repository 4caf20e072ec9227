"""A team switched on over a spread of times (BrainConfig.power_on_spread_s): a robot does nothing
and its radio is off until its time; the convoy's mission starts once the team is up; the loop's
wall time by part reaches result.json."""

from __future__ import annotations

from dataclasses import replace

from rescuemesh.maps import load_map, office_map_path
from rescuemesh.robot import robot_address
from rescuemesh.robot import events as ev
from rescuemesh.robot.records import power_on_s
from rescuemesh.runtime.inprocess.sim_loop import SimRuntime
from rescuemesh.scenarios import ScenarioOptions
from rescuemesh.scenarios.convoy import ConvoyScenario
from rescuemesh.scenarios.follow import FollowScenario


def test_power_on_times_are_spread_over_the_window_and_distinct():
    times = [power_on_s(address, 2.0) for address in range(1, 31)]
    assert all(0.0 <= t < 2.0 for t in times) and len(set(times)) == 30
    assert max(times) - min(times) > 1.6 and max(times) < 2.0 / 30 * 29  # spread over the window, not bunched
    assert power_on_s(7, 0.0) == 0.0  # no spread: all on at once


def test_a_robot_is_silent_with_its_radio_off_until_it_is_switched_on():
    scenario = FollowScenario(ScenarioOptions(), load_map(office_map_path()))
    config = scenario.sim_config()
    config = replace(config, brain=replace(config.brain, power_on_spread_s=2.0))
    rt = SimRuntime(scenario.map, scenario.starts(), config)
    on = {name: power_on_s(robot_address(name), 2.0) for name in scenario.starts()}
    assert len({round(t, 2) for t in on.values()}) == len(on)
    while rt.time < 2.1:
        rt.step()
        for name, at in on.items():
            address = robot_address(name)
            assert rt.medium.radio_enabled(address) == (rt.time >= at) == rt.powered_on(name)
            if rt.time < at:
                assert rt.brain(name).endpoint.stats.frames_sent == 0  # not even a Heartbeat
    sent_at = {}
    for record in rt.medium.records:
        sent_at.setdefault(record.transmitter, record.start_s)
    for name, at in on.items():  # each robot's first frame (its Heartbeat) goes out once it is on
        assert sent_at[robot_address(name)] >= at
    assert set(rt.wall_s) == {"world", "medium", "robots"} and all(v > 0.0 for v in rt.wall_s.values())


def test_the_30_robot_convoy_forms_its_first_links_without_giving_a_command_up():
    # this used to give robot_1's first Follow up at 0.5 s: 30 robots' first Heartbeats and their
    # relays all left on the first tick and jammed the air (seed 1 does so with everyone on at once)
    scenario = ConvoyScenario(ScenarioOptions(robots=30, seed=1), load_map(office_map_path()))
    rt = SimRuntime(scenario.map, scenario.starts(), scenario.sim_config())
    while rt.time < 4.5:
        rt.step(scenario.tick)
    given_up = [e for brain in rt.brains.values() for e in brain.log if isinstance(e, ev.CommandGivenUp)]
    assert not given_up, given_up
    assert scenario._links and scenario._links[0].confirmed() is not None  # robot_2 follows robot_1
