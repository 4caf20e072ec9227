"""docs/results.md defines every field of result.json (the end-to-end tests check each scenario's
result with tests/results_doc.py too); this file checks the check itself, and the page's coverage."""

import json

import pytest
from results_doc import documented_fields, result_fields, undocumented

from rescuemesh.cli import main


@pytest.fixture(scope="module")
def follow_result(tmp_path_factory):
    out = tmp_path_factory.mktemp("follow")
    assert main(["run", "follow", "--loss", "0.2", "--seed", "3", "--quiet", "--out", str(out)]) == 0
    return json.loads((out / "result.json").read_text())


def test_every_field_of_a_follow_result_is_defined(follow_result):
    assert undocumented(follow_result) == []


def test_a_field_added_without_a_definition_is_caught(follow_result):
    grown = json.loads(json.dumps(follow_result))
    grown["protocol"]["new_counter"] = 1
    grown["protocol"]["by_type"]["POSE_UPDATE"]["new_figure"] = 2.0
    grown["metrics"]["following_error_m"] = 0.1  # a leaf may change shape: still one field
    grown["robots"]["robot_2"]["endpoint"]["new_stat"] = 3
    assert undocumented(grown) == ["protocol.by_type.TYPE.new_figure", "protocol.new_counter",
                                   "robots.NAME.endpoint.new_stat"]


def test_the_page_defines_no_field_a_run_does_not_have(follow_result):
    # the general parts of result.json: a definition for a field that is gone is caught too
    documented = documented_fields()
    fields = result_fields(follow_result, documented)
    general = {f for f in documented if f.split(".")[0] in ("scenario", "seed", "success", "criteria", "sim_time_s",
                                                             "wall_time_s", "real_time_factor", "robots", "network",
                                                             "events")}
    general |= {f for f in documented if f.startswith("protocol.") and ".by_type.TYPE." not in f}
    assert sorted(general - fields) == []
