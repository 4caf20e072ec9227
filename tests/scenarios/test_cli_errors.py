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
             "show-scan", "show-cam", "land-on-top")
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
