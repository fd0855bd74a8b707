"""The README's "Your own robot" sequence is what it says: its console block is read out of the
README, each ``$ omni ...`` line is run (``omni_app.cli.main``) in pytest's tmp_path, and its
output is compared with the lines below it in the README (``error:`` lines with stderr and
exit status 2, the others with stdout and status 0).  The campaign file ``pendulum.toml`` it
names is the one shown on docs/usage/campaigns.md, read from that page.  Also: the rules the
section's table states (generate's refusals, what a pendulum's runs claim)."""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import pytest

from omni_app.cli import main

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
CAMPAIGNS = ROOT / "docs" / "usage" / "campaigns.md"
MODEL = "models/servo_pendulum/servo_pendulum.xml"


def section(text: str, heading: str) -> str:
    """The text of the ``## heading`` section (up to the next ``## ``)."""
    i = text.index(f"\n## {heading}\n")
    j = text.find("\n## ", i + 1)
    return text[i:j if j >= 0 else len(text)]


def console_steps(text: str) -> list[tuple[list[str], list[str]]]:
    """The ```console block of ``text`` as ``(argv after 'omni', expected output lines)``."""
    block = re.search(r"^```console\n(.*?)^```$", text, re.M | re.S).group(1)
    steps: list[tuple[list[str], list[str]]] = []
    for line in block.splitlines():
        if line.startswith("$ "):
            argv = shlex.split(line[2:])
            assert argv[0] == "omni", line
            steps.append((argv[1:], []))
        else:
            steps[-1][1].append(line)
    return steps


def pendulum_toml() -> str:
    """The campaign file the README's sequence names: the ```toml block after `pendulum.toml`
    on the campaign files page."""
    text = CAMPAIGNS.read_text()
    return re.search(r"`pendulum\.toml`.*?^```toml\n(.*?)^```$", text, re.M | re.S).group(1)


def test_the_parsers_read_blocks():
    text = "x\n```console\n$ omni a --b 'c d'\nout 1\nout 2\n$ omni e\n```\n"
    assert console_steps(text) == [(["a", "--b", "c d"], ["out 1", "out 2"]), (["e"], [])]
    assert "[sine]" in pendulum_toml() and "poses_deg =" not in pendulum_toml()


@pytest.mark.slow  # > 10 s (the default suite's time, 2 cores)
def test_the_readme_sequence_runs_as_printed(tmp_path, monkeypatch, capsys):
    steps = console_steps(section(README.read_text(), "Your own robot"))
    assert [argv[0] for argv, _ in steps] == ["generate", "identify", "discrepancy"]
    monkeypatch.chdir(tmp_path)
    (tmp_path / "models").symlink_to(ROOT / "models")  # the README's paths, read only
    (tmp_path / "pendulum.toml").write_text(pendulum_toml())
    for argv, expected in steps:
        code = main(argv)
        out, err = capsys.readouterr()
        if expected and expected[0].startswith("error:"):
            assert code == 2 and err.splitlines() == expected, (argv, err)
        else:
            assert code == 0, (argv, err)
            assert out.splitlines() == expected, (argv, out)
    assert not (tmp_path / "pendulum_params").exists()  # the refusal wrote nothing
    report = json.loads((tmp_path / "pendulum_report" / "report.json").read_text())
    assert report["gap_before"] == 0.0  # the model replays its own data exactly
    for p in (tmp_path / "pendulum_data").glob("*.json"):
        meta = json.loads(p.read_text())
        assert "gamma1_deg" not in meta and "gamma2_deg" not in meta
        assert (meta["joint"], meta["actuator"]) == ("pivot", "servo")


@pytest.mark.parametrize("argv, words", [
    ([], "--campaign paper is the Omni's"),
    (["--campaign", "sine"], "--campaign sine is the Omni's"),
    (["--campaign", "pendulum.toml", "--gamma1", "45"], "--gamma1/--gamma2 set the Omni's arm"),
    (["--campaign", "posed.toml"], "posed.toml: sine.poses_deg: this device has no arm to pose"),
    (["--campaign", "pendulum.toml", "--kp", "-1"], "--kp must be a finite P gain > 0"),
    (["--campaign", "pendulum.toml", "--command-limit", "0"], "--command-limit must be > 0"),
])
def test_generate_refuses_poses_on_a_device_without_the_arm(tmp_path, monkeypatch, capsys, argv, words):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "pendulum.toml").write_text(pendulum_toml())
    (tmp_path / "posed.toml").write_text(pendulum_toml().replace("[sine]\n", "[sine]\nposes_deg = [[45, 90]]\n"))
    code = main(["generate", "--model", str(ROOT / MODEL), "--joint", "pivot", "--actuator", "servo",
                 "--out", "o", *argv])
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1 and err.startswith("error: ") and words in err, err
    assert not (tmp_path / "o").exists()


def test_generate_refuses_a_half_target_and_a_poseless_group_on_the_omni(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "pendulum.toml").write_text(pendulum_toml())
    assert main(["generate", "--model", str(ROOT / MODEL), "--joint", "pivot", "--out", "o"]) == 2
    assert "give --joint and --actuator together" in capsys.readouterr().err
    assert main(["generate", "--campaign", "pendulum.toml", "--out", "o"]) == 2
    assert "pendulum.toml: sine.poses_deg: missing" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_validate_refuses_runs_without_a_pose(tmp_path, monkeypatch, capsys):
    """validate (as identify in the README's sequence) refuses the pendulum's runs in one line
    that names what to run instead."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "ref.csv").write_text("t,r\n0,0\n0.5,0.1\n1,0.1\n")
    assert main(["generate", "--model", str(ROOT / MODEL), "--joint", "pivot", "--actuator", "servo",
                 "--reference", "ref.csv", "--out", "d"]) == 0
    capsys.readouterr()
    (tmp_path / "params.json").write_text(json.dumps({"poses": [], "inertia_model": None, "alpha_model": None}))
    assert main(["validate", "d", "--params", "params.json", "--out", "v"]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "d/ref.json: no arm pose" in err
    assert "omni validate is the paper's method for the Omni's gravity-free yaw axis" in err
    assert "omni discrepancy --measured d --model FILE --joint J --actuator A" in err
