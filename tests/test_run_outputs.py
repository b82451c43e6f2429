"""`mjrft run`'s table: decimated by default to what the figures draw, CSV or Parquet, read
back exactly."""

import json

import numpy as np
import pytest

from mjrft.app import cli, simulate

SPHERE = ["run", "sphere_drop", "--triangles", "200"]


def _run(out, *extra: str) -> dict:
    assert cli.main([*SPHERE, "--out", str(out), *extra]) == 0
    return json.loads((out / cli.RUN_JSON).read_text())


def test_the_default_table_has_about_the_rows_the_figures_draw(tmp_path, capsys):
    """5 s at dt = 1 ms: 5000 steps, a row every 5000 // 2000 = 2 steps, the initial state and
    the final one: 2501 rows; --record-every 1 keeps every step."""
    record = _run(tmp_path / "a", "--duration", "5", "--no-plots")
    steps = 5000
    k = steps // simulate.FIGURE_ROWS
    assert record["record_every_steps"] == k == 2
    assert record["rows"] == steps // k + 1
    assert "2501 rows (one per 2 steps)" in capsys.readouterr().out
    every = _run(tmp_path / "b", "--duration", "5", "--no-plots", "--record-every", "1")
    assert every["record_every_steps"] == 1 and every["rows"] == steps + 1
    _, a = simulate.read_table(tmp_path / "a" / cli.RUN_CSV)
    _, b = simulate.read_table(tmp_path / "b" / cli.RUN_CSV)
    np.testing.assert_array_equal(a[:-1], b[:-1:k])  # the same states, every k-th
    np.testing.assert_array_equal(a[-1], b[-1])
    # A short run keeps every step.
    assert simulate.figure_record_every(1999) == 1


def test_a_parquet_table_holds_exactly_the_csvs_values(tmp_path):
    csv = _run(tmp_path / "csv", "--duration", "0.3")
    parquet = _run(tmp_path / "pq", "--duration", "0.3", "--table-format", "parquet",
                   "--all-figures")  # fmt: skip
    assert not (tmp_path / "pq" / cli.RUN_CSV).exists()  # the journal goes
    assert parquet["outputs"][0] == str(tmp_path / "pq" / cli.RUN_PARQUET)
    cols_a, a = simulate.read_table(tmp_path / "csv" / cli.RUN_CSV)
    cols_b, b = simulate.read_table(tmp_path / "pq" / cli.RUN_PARQUET)
    assert cols_a == cols_b and parquet["rows"] == csv["rows"] == len(b)
    np.testing.assert_array_equal(a, b)
    assert {p.name for p in (tmp_path / "pq").glob("*.png")} == set(cli.RUN_PLOTS)


def test_a_run_folder_with_a_parquet_table_or_an_svg_figure_holds_a_run(tmp_path, capsys):
    for name in (cli.RUN_PARQUET, "rft_summary.svg"):
        out = tmp_path / name
        out.mkdir()
        (out / name).write_text("precious")
        assert cli.main([*SPHERE, "--duration", "0.01", "--out", str(out)]) == 2
        assert f"already holds a run ({name})" in capsys.readouterr().err


@pytest.mark.parametrize("fmt", ["svg", "pdf"])
def test_figure_format(tmp_path, fmt):
    record = _run(tmp_path, "--duration", "0.3", "--figure-format", fmt, "--all-figures")
    figures = sorted(p.name for p in tmp_path.glob(f"*.{fmt}"))
    assert figures == sorted(f"{n}.{fmt}" for n in cli.RUN_FIGURES)
    assert not list(tmp_path.glob("*.png"))
    assert set(record["outputs"][1:]) == {str(tmp_path / f) for f in figures}


def test_the_table_is_read_back_exactly_nan_and_inf_included(tmp_path):
    columns = ["time_s", "a"]
    sink = simulate.CsvSink(tmp_path / "t.csv", columns)
    rows = [np.array([0.0, np.nan]), np.array([0.1, np.inf]), np.array([0.2, -1e-300])]
    for r in rows:
        sink.append(r)
    sink.close()
    rec = simulate.Recording.from_file(tmp_path / "t.csv", [])
    np.testing.assert_array_equal(rec.array(), np.array(rows))
    simulate.write_parquet(tmp_path / "t.csv", tmp_path / "t.parquet")
    np.testing.assert_array_equal(simulate.read_table(tmp_path / "t.parquet")[1], np.array(rows))


def test_a_completed_runs_figures_stay_within_its_simulation_time(tmp_path, capsys):
    """0.1 s of a sphere takes a few milliseconds: no figure fits, each is named, and the table
    is not even read back; --all-figures draws them all."""
    record = _run(tmp_path / "a", "--duration", "0.1")
    assert record["figures_skipped"] == ["rft_summary", "forces_vs_time", "forces_vs_depth"]
    assert record.get("timing", {}).get("plots_s", 0.0) <= record["timing"]["simulation_s"]
    assert not list((tmp_path / "a").glob("*.png"))
    assert "figures not drawn, to stay within the simulation's" in capsys.readouterr().out
    every = _run(tmp_path / "b", "--duration", "0.1", "--all-figures")
    assert every["figures_skipped"] == [] and len(every["outputs"]) == 4
