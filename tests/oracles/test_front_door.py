"""The mesh nodes' front door in the simulated medium (transport/front_door.py): the network cache
in flat slots decides as its OrderedDict oracle (oracles/cache.py) did, and a team whose copies are
recognised by the compiled kernel ends exactly as the same team whose every copy goes through
MeshNode.receive (the oracle: the node's own Python path)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from oracles.cache import NetworkCache as OracleCache
from rescuemesh.mesh import MeshConfig, MeshNode, NetworkStack
from rescuemesh.mesh.cache import NetworkCache
from rescuemesh.mesh.security import FrameSealer
from rescuemesh.protocol import DataKind, Endpoint, EndpointConfig, Pose, Stop
from rescuemesh.mesh.keys import team_key_from_seed
from rescuemesh.radio import DiscChannel
from rescuemesh.transport import front_door as fd
from rescuemesh.transport.sim_medium import SimMedium


@pytest.mark.parametrize("size, lifetime", [(1, 0.3), (4, 0.5), (16, 0.75), (128, 0.75)])
def test_the_slotted_cache_decides_as_its_ordereddict_oracle(size, lifetime):
    rng = np.random.default_rng(size)
    cache, oracle = NetworkCache(size, lifetime), OracleCache(size, lifetime)
    now = 0.0
    for step in range(3000):
        if step == 1000:  # moved into lent buffers midway, as the medium does at attach
            words, heard = np.zeros(len(cache.words), dtype=np.int64), np.zeros(size)
            cache.use_storage(memoryview(words), memoryview(heard))
        now += float(rng.choice([0.0, 0.001, 0.05, 0.3]))
        key = bytes(rng.integers(0, 4, int(rng.integers(1, 30)), dtype=np.uint8))[:3]
        assert cache.check_and_add(key, now) == oracle.check_and_add(key, now)
        assert len(cache) == len(oracle) and all(k in cache for k in oracle.keys())


def _team(front_door: bool, config: MeshConfig, seed: int = 3, robots: int = 10, loss: float = 0.2):
    """Robots 4 m apart on a line of 10 m discs (two or three hops end to end), authenticated."""
    medium = SimMedium(DiscChannel(), seed, extra_loss=loss)
    medium.front_door = front_door
    sealer = FrameSealer.from_team_key(team_key_from_seed(seed))
    stacks = []
    for address in range(1, robots + 1):
        endpoint = Endpoint(address, EndpointConfig(initial_ttl=4))
        stack = NetworkStack(endpoint, MeshNode(address, config, sealer))
        medium.attach(address, stack, lambda x=4.0 * address: (x, 0.0))
        stacks.append(stack)
    return medium, stacks


def _run(front_door: bool, config: MeshConfig, seconds: float = 4.0):
    """Heartbeats, commands, pose updates and segmented data between random robots; returns what
    every robot ended with and how many copies the front door recognised."""
    medium, stacks = _team(front_door, config)
    rng = np.random.default_rng(5)
    heard = [[] for _ in stacks]
    t = 0.0
    while t < seconds:
        t = round(t + 0.05, 9)
        medium.pump(t)
        for i, stack in enumerate(stacks):
            while (event := stack.endpoint.next_event()) is not None:
                heard[i].append(repr(event))
            while (event := stack.next_event()) is not None:
                heard[i].append(repr(event))
            if round(t * 20) % 20 == i:
                stack.endpoint.send_heartbeat(t)
            if rng.random() < 0.15:
                dst = int(rng.integers(1, len(stacks) + 1))
                if dst != stack.address:
                    kind = rng.random()
                    if kind < 0.4:
                        stack.endpoint.send_command(dst, Stop(), t)
                    elif kind < 0.9:
                        stack.endpoint.send_pose_update(dst, Pose(float(t), 1.0, 0.0, 0.5), t)
                    else:
                        stack.endpoint.send_data(dst, DataKind.RAW, 0, bytes(rng.integers(0, 256, 60, dtype=np.uint8)), t)
        medium.flush(t)
    nodes = [(dataclasses.asdict(s.node.stats), dataclasses.asdict(s.endpoint.stats), heard[i],
              sorted(s.node.cache.held(t))) for i, s in enumerate(stacks)]
    return nodes, medium.stats.as_dict()


# a small cache (keys evicted while copies still come) and a short lifetime (keys expired when they do)
@pytest.mark.parametrize("config", [MeshConfig(cache_size=24), MeshConfig(cache_size=64, cache_lifetime_s=0.012)],
                         ids=["evicted", "expired"])
def test_a_team_ends_as_it_does_with_every_copy_through_the_node(monkeypatch, config):
    recognised = []
    sort = fd.FrontDoor.sort

    def counting(self, state, *args):
        receivers = sort(self, state, *args)
        recognised.append(int((state == 0).sum()) - len(receivers))
        return receivers

    monkeypatch.setattr(fd.FrontDoor, "sort", counting)
    with_door, medium = _run(True, config)
    without, medium_without = _run(False, config)
    assert sum(recognised) > 100  # many copies were recognised at the front door
    assert medium == medium_without
    for robot, (a, b) in enumerate(zip(with_door, without), start=1):
        assert a[0] == b[0], f"robot {robot}'s mesh counters"
        assert a[1:] == b[1:], f"robot {robot}'s endpoint, events and cache"
