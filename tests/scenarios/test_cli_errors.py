"""Bad input gets one clear line on stderr and exit 2, never a traceback."""

import subprocess
import sys

import pytest

from rescuemesh.cli import main


@pytest.fixture
def broken_map(tmp_path):
    path = tmp_path / "broken.yaml"
    path.write_text("walls:\n  - [0, 0, 1]\n")
    return path


@pytest.mark.parametrize("argv, words", [
    (["run", "dance"], "unknown scenario"),
    (["run", "move-around", "--radius", "0"], "radius"),
    (["run", "move-around", "--radius", "-1.5"], "radius"),
    (["run", "move-around", "--radius", "50"], "larger than the map"),
    (["run", "move-around", "--radius", "nan"], "radius"),
    (["run", "follow", "--loss", "1.0"], "--loss"),
    (["run", "follow", "--loss", "-0.1"], "--loss"),
    (["run", "follow", "--loss", "lots"], "invalid float"),
    (["run", "follow", "--map", "/nonexistent/map.yaml"], "map.yaml"),
    (["run", "follow", "--start", "robot_9=1,1,0"], "robot_9"),
    (["run", "follow", "--start", "robot_x=1,1,0"], "unknown robot"),
    (["run", "follow", "--start", "robot_1"], "NAME=X,Y,YAW"),
    (["run", "follow", "--start", "robot_1=1,a,0"], "not a number"),
    (["run", "follow", "--goal", "1"], "X,Y"),
    (["run", "follow", "--goal", "-50,-50"], "goal"),
    (["run", "follow", "--time-limit", "-3"], "--time-limit"),
    (["run", "follow", "--time-limit", "inf"], "--time-limit"),
    (["run", "follow", "--seed", "-1"], "--seed"),
    (["run", "follow", "--start", "robot_1=4.5,4.5,0", "--start", "robot_2=4.6,4.6,0"], "apart"),
    (["run", "follow", "--outage", "3"], "--outage applies to the disconnect scenario"),
    (["run", "disconnect", "--outage", "-3"], "--outage"),
    (["run", "disconnect", "--outage", "nan"], "--outage"),
    (["run", "disconnect", "--outage", "601"], "--outage"),
    (["run", "follow", "--radio", "wifi"], "invalid choice"),
    (["run", "follow", "--robots", "5"], "--robots applies to the convoy scenario, not to follow"),
    (["run", "convoy", "--robots", "1"], "--robots must be from 2 to 254"),
    (["run", "convoy", "--robots", "-3"], "--robots must be from 2 to 254"),
    (["run", "convoy", "--robots", "255"], "--robots must be from 2 to 254"),
    (["run", "convoy", "--robots", "many"], "invalid int"),
    (["run", "convoy", "--robots", "60"], "room for 45 robots behind the leader"),
    (["run", "convoy", "--start", "robot_7=1,1,0"], "unknown robot 'robot_7'"),
    (["radio-map"], "--from"),
    (["radio-map", "--from", "2.2,2.2"], "inside a wall"),
    (["radio-map", "--from", "100,2"], "off the map"),
    (["radio-map", "--from", "1,1", "--map", "/nonexistent/map.yaml"], "map.yaml"),
    (["radio-map", "--from", "1,1", "--seed", "-2"], "--seed"),
    (["ble-check", "--hci", "usb:0"], "--hci names 1 controller"),
    (["run", "follow", "--key", "/nonexistent/team.key"], "no such key file"),
    (["run", "follow", "--key", "README.md"], "README.md"),
    (["run", "follow", "--key", "x", "--insecure"], "contradict"),
    (["keys"], "required"),
    (["keys", "new"], "file"),
    (["keys", "new", "README.md"], "exists"),
    (["bench", "--seed", "-1"], "--seed"),
    (["fly"], "invalid choice"),
    ([], "required"),
])
def test_bad_arguments_exit_2_with_one_line(argv, words, capsys, tmp_path):
    code = main(argv + (["--out", str(tmp_path)] if argv[:1] in (["run"], ["radio-map"]) and len(argv) > 1 else []))
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and err.startswith("rescuemesh: error:")
    assert words in err


def test_broken_map_file_exits_2_naming_the_file(broken_map, capsys, tmp_path):
    assert main(["run", "follow", "--map", str(broken_map), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "broken.yaml" in err and len(err.strip().splitlines()) == 1


def test_real_process_prints_no_traceback(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "rescuemesh", "run", "move-around", "--radius", "-1",
                           "--out", str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and "radius" in proc.stderr


def test_scenarios_lists_every_scenario_with_one_line_each(capsys):
    assert main(["scenarios"]) == 0
    lines = capsys.readouterr().out.splitlines()
    names = ("follow", "stop", "move-around", "relay", "disconnect", "spoof", "goto", "return", "priority",
             "show-scan", "show-cam", "land-on-top", "convoy")
    assert [line.split()[0] for line in lines] == list(names)


@pytest.mark.parametrize("where", ["a_file", "/proc/rescuemesh"])
def test_an_output_folder_that_cannot_be_written_is_refused_before_running(where, tmp_path, capsys):
    # this used to run the whole scenario and then print a FileExistsError / FileNotFoundError traceback
    target = tmp_path / where if where == "a_file" else where
    if where == "a_file":
        target.write_text("not a folder")
    assert main(["run", "follow", "--out", str(target)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "cannot write to output folder" in err


def test_bench_refuses_a_folder_as_its_output_file(tmp_path, capsys):
    assert main(["bench", "--out", str(tmp_path)]) == 2
    assert "is a folder" in capsys.readouterr().err


def test_relay_on_another_map_needs_every_start(tmp_path, capsys):
    path = tmp_path / "plain.yaml"
    path.write_text("name: plain\nwalls:\n  - [0, 0, 10, 0.1]\n  - [0, 9.9, 10, 10]\n  - [0, 0, 0.1, 10]\n"
                    "  - [9.9, 0, 10, 10]\nstarts:\n  robot_1: [1, 1, 0]\n  robot_2: [2, 2, 0]\n  robot_3: [3, 3, 0]\n")
    assert main(["run", "relay", "--map", str(path), "--out", str(tmp_path / "out")]) == 2
    assert "relay needs --start for robot_1, robot_2 and robot_3" in capsys.readouterr().err



@pytest.mark.parametrize("scenario, role", [("land-on-top", "the drone"), ("priority", "the operator station")])
def test_a_fourth_robot_on_another_map_needs_its_start(scenario, role, tmp_path, capsys):
    path = tmp_path / "plain.yaml"
    path.write_text("name: plain\nwalls:\n  - [0, 0, 10, 0.1]\n  - [0, 9.9, 10, 10]\n  - [0, 0, 0.1, 10]\n"
                    "  - [9.9, 0, 10, 10]\nstarts:\n  robot_1: [1, 1, 0]\n  robot_2: [2, 2, 0]\n  robot_3: [3, 3, 0]\n")
    assert main(["run", scenario, "--map", str(path), "--out", str(tmp_path / "out")]) == 2
    assert f"{scenario} needs --start robot_4=X,Y,YAW ({role}) on map 'plain'" in capsys.readouterr().err

# --- rough edges a new user hit on real maps (issue: scale and real maps) -----------------------------


def test_a_negative_goal_is_a_value_not_an_option(tmp_path, capsys):
    # this used to fail with "expected one argument": only --goal=-7.95,0 worked
    code = main(["run", "follow", "--goal", "-7.95,0", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and "goal (-7.95, 0.00) is inside an obstacle or off the map" in err
    assert "expected one argument" not in err


def test_a_negative_transmitter_position_is_a_value_too(capsys, tmp_path):
    assert main(["radio-map", "--from", "-3,4", "--out", str(tmp_path)]) == 2
    assert "transmitter (-3, 4) is off the map" in capsys.readouterr().err


@pytest.mark.parametrize("argv, words", [
    (["--start", "robot_2=5,4.6,0", "--start", "robot_2=5,4,0"], "--start robot_2 is given twice"),
    (["--goal", ""], "--goal is empty"),
    (["--out", ""], "--out: is empty"),
])
def test_options_given_twice_or_empty_are_refused(argv, words, capsys, tmp_path):
    # this used to keep the last --start silently, and to accept an empty --goal or --out
    argv = ["run", "follow", *argv] + ([] if "--out" in argv else ["--out", str(tmp_path)])
    assert main(argv) == 2
    assert words in capsys.readouterr().err


def test_an_unreachable_goal_says_why_in_the_summary(tmp_path, capsys):
    # this used to print only "[ ] leader reached its goal"; the reason was in result.json alone
    boxed = tmp_path / "boxed.yaml"
    boxed.write_text("name: boxed\nwalls:\n  - [0, 0, 10, 0.1]\n  - [0, 9.9, 10, 10]\n  - [0, 0, 0.1, 10]\n"
                     "  - [9.9, 0, 10, 10]\n  - [6, 6, 9, 6.1]\n  - [6, 8.9, 9, 9]\n  - [6, 6, 6.1, 9]\n"
                     "  - [8.9, 6, 9, 9]\nstarts:\n  robot_1: [2, 2, 0]\n  robot_2: [1, 2, 0]\n  robot_3: [2, 4, 0]\n")
    code = main(["run", "follow", "--map", str(boxed), "--goal", "7.5,7.5", "--quiet", "--out", str(tmp_path / "o")])
    out = capsys.readouterr().out
    assert code == 1 and "[ ] leader reached its goal (FAILED: navigation aborted: no path)" in out


class _ClosedPipe:
    """A stdout whose reader went away."""

    def write(self, text):
        raise BrokenPipeError(32, "Broken pipe")

    def flush(self):
        raise BrokenPipeError(32, "Broken pipe")


def test_a_reader_that_goes_away_ends_the_run_quietly(monkeypatch, capsys):
    # this used to end `rescuemesh run follow | head -1` with a BrokenPipeError traceback and exit 1
    monkeypatch.setattr("sys.stdout", _ClosedPipe())
    assert main(["scenarios"]) == 0
