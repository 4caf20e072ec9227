"""Scenarios by name: each sets robots up, scripts a mission, and judges it.

Owns: the registry. Must not know: the command line, output files.
"""

from rescuemesh.scenarios.base import Scenario, ScenarioError, ScenarioOptions, Verdict
from rescuemesh.scenarios.convoy import ConvoyScenario
from rescuemesh.scenarios.disconnect import DisconnectScenario
from rescuemesh.scenarios.follow import FollowScenario
from rescuemesh.scenarios.goto import GotoScenario, ReturnScenario
from rescuemesh.scenarios.land_on_top import LandOnTopScenario
from rescuemesh.scenarios.priority import PriorityScenario
from rescuemesh.scenarios.move_around import MoveAroundScenario
from rescuemesh.scenarios.relay import RelayScenario
from rescuemesh.scenarios.show import ShowCamScenario, ShowScanScenario
from rescuemesh.scenarios.spoof import SpoofScenario
from rescuemesh.scenarios.stop import StopScenario

SCENARIOS: dict[str, type[Scenario]] = {
    cls.name: cls
    for cls in (FollowScenario, StopScenario, MoveAroundScenario, RelayScenario, DisconnectScenario, SpoofScenario,
                GotoScenario, ReturnScenario, PriorityScenario, ShowScanScenario, ShowCamScenario,
                LandOnTopScenario, ConvoyScenario)
}


def get_scenario(name: str) -> type[Scenario]:
    """The scenario class called `name`; ScenarioError lists the known ones."""
    try:
        return SCENARIOS[name]
    except KeyError:
        raise ScenarioError(f"unknown scenario {name!r}; known: {', '.join(SCENARIOS)}") from None


__all__ = ["SCENARIOS", "Scenario", "ScenarioError", "ScenarioOptions", "Verdict", "get_scenario"]
