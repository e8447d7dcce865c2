"""The command line: outputs of `usv-mj run`, and bad input ending in one clear message and exit 2."""

import json
import subprocess
import sys

import pytest

from usv_mj.cli.main import main


def run_cli(args, tmp_path):
    return subprocess.run([sys.executable, "-m", "usv_mj.cli.main", *args], capture_output=True, text=True,
                          cwd=tmp_path, timeout=600)


def test_run_writes_summary_figures_and_report(tmp_path):
    out = tmp_path / "out"
    code = main(["run", "--plant", "analytic", "--duration", "25", "--no-video", "--no-log", "-q", "--out", str(out)])
    assert code == 0
    s = json.loads((out / "summary.json").read_text())
    for key in ("preset", "plant", "duration_s", "control_period_s", "errors_at", "max_abs_error_after_20s",
                "funnel_violations", "first_violation_s", "s2_clamps", "quantizer_switches", "wall_time_s",
                "realtime_factor"):
        assert key in s
    assert s["plant"] == "analytic" and s["duration_s"] == 25.0 and s["control_period_s"] == 0.001
    assert set(s["errors_at"]) == {"5", "10", "20"} and set(s["errors_at"]["5"]) == {"x", "y", "psi"}
    assert set(s["quantizer_switches"]) == {"u", "r"}
    assert sorted(p.name for p in (out / "figures").iterdir()) == [
        "fig1_trajectory.png", "fig2_error_x.png", "fig3_error_y.png", "fig4_error_psi.png",
        "fig5_tau_u.png", "fig6_tau_r.png", "fig7_weights.png"]
    report = (out / "report.md").read_text()
    assert "5.32" in report and "6.81" in report  # the paper's Tables 1 and 2 beside ours
    assert s["step_check"]["ok"]  # SPEC §5: halving the step moves the errors by < 1 cm, 0.01 rad


BAD = [
    ("[quantizer]\ndelta_u = 1.5\n", "quantizer.delta_u"),
    ("[quantizer]\nu_min_r = 0.0\n", "quantizer.u_min_r"),
    ("[funnel]\nrho_xy = [2.0, 3.0]\n", "rho_xy"),
    ("[controler]\nk1 = 3\n", "controler"),
    ("[controller]\nk9 = 3\n", "controller.k9"),
    ("duration = 10\n[initial\neta = [1, 2, 3]\n", "not valid TOML"),
    ('preset = "papr"\n', "papr"),
    ("[initial]\neta = [1.0, 2.0]\n", "initial.eta"),
    ("[trajectory]\nkind = \"spiral\"\n", "trajectory"),
]


@pytest.mark.parametrize("text, named", BAD)
def test_bad_scenario_exits_2_with_one_clear_message_and_no_output(tmp_path, text, named):
    scenario = tmp_path / "bad.toml"
    scenario.write_text(text)
    out = tmp_path / "out"
    proc = run_cli(["run", "--scenario", str(scenario), "--out", str(out), "--no-video"], tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert named in proc.stderr
    assert "Traceback" not in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
    assert not out.exists()


def test_set_override_and_presets_listing(tmp_path, capsys):
    assert main(["presets"]) == 0
    listed = capsys.readouterr().out
    assert "paper" in listed and "paper-printed" in listed and "harsh" in listed
    proc = run_cli(["run", "--set", "disturbance.scale=-1", "--no-video", "--out", "x"], tmp_path)
    assert proc.returncode == 2 and "disturbance.scale" in proc.stderr


def test_closed_pipe_ends_the_command_quietly():
    """`usv-mj presets paper | head -0`: the reader is gone before the first line; exit 141 as a
    Unix tool killed by SIGPIPE would, with no traceback."""
    proc = subprocess.Popen([sys.executable, "-m", "usv_mj.cli.main", "presets", "paper"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    proc.stdout.close()                     # before the interpreter has even started writing
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141, err
    assert "Traceback" not in err and "BrokenPipe" not in err, err


def test_one_flag_name_per_concept_and_the_old_ones_still_work(capsys):
    """-q/--quiet, --size, --scenario in every command that has the concept; the old spellings
    (--no-progress, --video-size, --base) still parse, hidden from --help; bare usv-mj is a short usage."""
    from usv_mj.cli.main import build_parser, main

    assert main([]) == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: usv-mj COMMAND") and len(err.splitlines()) < 8
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices
    for name, p in sub.items():
        flags = {o for a in p._actions for o in a.option_strings}
        helped = {o for a in p._actions if a.help != "==SUPPRESS==" for o in a.option_strings}
        if flags & {"--no-progress", "-q"}:
            assert {"-q", "--quiet"} <= helped, name
        assert not helped & {"--no-progress", "--video-size", "--base"}, name
        assert "``" not in (p.description or "") and "issue" not in (p.description or "").lower(), name
    assert parser.parse_args(["render", "x.mcap", "--no-progress"]).quiet
    assert parser.parse_args(["render", "x.mcap", "-q"]).quiet
    assert not parser.parse_args(["render", "x.mcap"]).quiet
    assert parser.parse_args(["env", "track", "--video-size", "64x48"]).size == (64, 48)
    assert parser.parse_args(["env", "track", "--size", "64x48"]).size == (64, 48)
    assert parser.parse_args(["env", "track"]).size == (640, 360)
    assert parser.parse_args(["capability", "--load", "current", "--scenario", "paper-limited"]).base == "paper-limited"
    assert parser.parse_args(["sweep", "s.toml"]).out is None          # --out has a default now
