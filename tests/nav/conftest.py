"""Fixtures for the navigation tests: costmaps of the synthetic worlds in navworld.py."""

import pytest
from navworld import corridor, room_with_door

from rescuemesh.nav import Costmap


@pytest.fixture(scope="session")
def room_costmap() -> Costmap:
    return Costmap(room_with_door())


@pytest.fixture(scope="session")
def corridor_costmap() -> Costmap:
    return Costmap(corridor())
