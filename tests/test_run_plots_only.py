"""`mjrft run MODEL --out DIR --plots-only`: a finished run's figures drawn from its table."""

from __future__ import annotations

from mjrft.app import cli


def test_a_short_run_draws_its_figures_afterwards_from_its_table(tmp_path, capsys):
    out = tmp_path / "run"
    base = ["run", "sphere_drop", "--triangles", "200", "--out", str(out)]
    assert cli.main([*base, "--duration", "0.2"]) == 0
    assert not list(out.glob("*.png"))  # too short a simulation for its figures by default
    table_before = (out / cli.RUN_CSV).read_bytes()
    assert cli.main([*base, "--plots-only", "--figure-format", "svg"]) == 0
    drawn = sorted(p.name for p in out.glob("*.svg"))
    assert drawn and all(p.stat().st_size > 1000 for p in out.glob("*.svg")), drawn
    assert (out / cli.RUN_CSV).read_bytes() == table_before  # nothing simulated or rewritten
    assert "drew" in capsys.readouterr().out


def test_plots_only_refuses_a_folder_without_a_table_or_of_another_model(tmp_path, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    assert cli.main(["run", "sphere_drop", "--out", str(empty), "--plots-only"]) == 2
    assert "holds no run table" in capsys.readouterr().err
    out = tmp_path / "run"
    assert cli.main(["run", "sphere_drop", "--triangles", "200", "--out", str(out),
                     "--duration", "0.05"]) == 0  # fmt: skip
    assert cli.main(["run", "wheel_rig", "--out", str(out), "--plots-only"]) == 2
    assert "written by another model" in capsys.readouterr().err


def test_a_run_needs_its_duration(tmp_path, capsys):
    assert cli.main(["run", "sphere_drop", "--out", str(tmp_path / "x")]) == 2
    assert "--duration SECONDS is required" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()  # refused before anything was written
