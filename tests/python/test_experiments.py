"""`graybox-lab experiment … --quick`: the files are written, the tables are well formed, the PNGs
decode and show their series, a rerun with the same --out resumes instead of recomputing, a
run cut short continues with only its missing cells, and other settings in the same --out are
refused. No test here asserts a research outcome: the quick runs are far too small for one."""

import csv
import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

# matplotlib's blue (graybox's first series colour) and the paper bars' gray.
BLUE = (0x1F, 0x77, 0xB4)
GRAY = (0x99, 0x99, 0x99)

EXPERIMENTS = {
    "data-efficiency": ("data_efficiency.png", GRAY),
    "rollout": ("rollouts.png", BLUE),
    "mbrl": ("mbrl.png", BLUE),
    "multistep": ("horizons.png", BLUE),
    "ensemble": ("sigma_vs_error.png", BLUE),
}


def experiment(binary: str, *args: str, ok: bool = True) -> subprocess.CompletedProcess:
    p = subprocess.run([binary, "experiment", *args], capture_output=True, text=True,
                       timeout=300)
    if ok:
        assert p.returncode == 0, p.stderr
    return p


def markdown_tables(text: str) -> list[list[list[str]]]:
    """Every Markdown table in `text` as rows of cells (separator rows dropped)."""
    tables, rows = [], []
    for line in text.splitlines() + [""]:
        if line.startswith("|"):
            rows.append([c.strip() for c in line.strip().strip("|").split("|")])
        elif rows:
            tables.append(rows)
            rows = []
    return tables


def assert_well_formed(table: list[list[str]]):
    header, sep, *body = table
    assert all(set(c) <= set("-:") and c for c in sep), sep
    assert body, "a table with no rows"
    for row in [sep, *body]:
        assert len(row) == len(header), (header, row)
    assert all(c for row in body for c in row), "an empty cell"


def share_of(png: Path, rgb: tuple[int, int, int], tol: int = 12) -> float:
    """The share of the image's pixels within `tol` of colour `rgb` in every channel."""
    px = np.asarray(Image.open(png).convert("RGB"), dtype=int)
    return float((np.abs(px - np.array(rgb)) <= tol).all(axis=-1).mean())


@pytest.mark.parametrize("name", EXPERIMENTS)
def test_quick_run_writes_its_results_and_a_rerun_resumes(lab_bin, tmp_path, name):
    out = tmp_path / name
    experiment(lab_bin, name, "--quick", "--out", str(out))
    png, colour = EXPERIMENTS[name]
    for f in ["results.md", "results.csv", "run.json", "cells.jsonl", png]:
        assert (out / f).is_file(), f

    run = json.loads((out / "run.json").read_text())
    assert run["experiment"] == name and run["complete"] is True
    assert run["invocations"] == 1 and run["wall_seconds"] > 0
    assert run["graybox_version"] and len(run["commit"]) in (40, len("unknown"))
    assert "--quick" in run["command"] and run["settings"]

    md = (out / "results.md").read_text()
    tables = markdown_tables(md)
    assert tables, md
    for t in tables:
        assert_well_formed(t)
    assert f"]({png})" in md
    if name == "rollout":
        # --quick adds the trajectory rows: the one-step loss and windows of 3.
        rows = [r[0] for r in tables[0][2:]]
        assert rows[2:] == ["MVF, trajectories, H = 1", "MVF, trajectories, H = 3"], rows

    with open(out / "results.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert rows and all(None not in r and None not in r.values() for r in rows)

    img = Image.open(out / png)
    img.load()
    assert img.format == "PNG" and img.width >= 800 and img.height >= 400
    # Looked at: mostly white background with the experiment's series drawn on it.
    assert share_of(out / png, (255, 255, 255), tol=0) > 0.3
    # A 2-px line across a third of the plot is ~0.15% of the pixels.
    assert share_of(out / png, colour) > 0.0005, f"no {colour} series in {png}"

    cells = (out / "cells.jsonl").read_bytes()
    again = experiment(lab_bin, name, "--quick", "--out", str(out))
    assert (out / "cells.jsonl").read_bytes() == cells, "the rerun recomputed finished cells"
    assert "earlier" in again.stderr
    assert (out / "results.md").read_text() == md
    rerun = json.loads((out / "run.json").read_text())
    assert rerun["invocations"] == 2 and rerun["started"] == run["started"]


def test_mbrl_plans_with_either_planner(lab_bin, tmp_path):
    """DIRCOL (the paper's planner) by default, iLQR on request; run.json and results.md say
    which, and the reference is the better of both on the true model, the same for either."""
    refs = {}
    for planner, args in [("dircol", []), ("ilqr", ["--planner", "ilqr"])]:
        out = tmp_path / planner
        experiment(lab_bin, "mbrl", "--quick", *args, "--out", str(out))
        run = json.loads((out / "run.json").read_text())
        assert run["settings"]["planner"] == planner, run["settings"]
        md = (out / "results.md").read_text()
        name = {"dircol": "DIRCOL", "ilqr": "iLQR"}[planner]
        assert f"Planner on the learned models: {name}." in md, md
        cells = [json.loads(line) for line in (out / "cells.jsonl").read_text().splitlines()]
        refs[planner] = next(c["value"] for c in cells if c["key"] == "reference")
        episodes = [c["value"] for c in cells
                    if c["key"].startswith("MVB/") and "/episode" in c["key"]]
        assert len(episodes) == 2 and all(e["plan_cost"] is not None for e in episodes), episodes
    assert refs["dircol"] == refs["ilqr"], refs
    assert refs["dircol"]["planner"] in ("DIRCOL", "iLQR")


def test_mbrl_periodic_trains_on_both_angles_as_angles(lab_bin, tmp_path):
    """--periodic marks both angles of every model of the loop; without it the settings carry
    no such field, so directories of earlier runs continue."""
    out = tmp_path / "periodic"
    experiment(lab_bin, "mbrl", "--quick", "--periodic", "--out", str(out))
    assert json.loads((out / "run.json").read_text())["settings"]["periodic"] is True
    state = json.loads((out / "state-MVB-seed0.json").read_text())
    assert state["checkpoint"]["config"]["periodic"] == [True, True]
    plain = tmp_path / "plain"
    experiment(lab_bin, "mbrl", "--quick", "--episodes", "1", "--out", str(plain))
    assert "periodic" not in json.loads((plain / "run.json").read_text())["settings"]


def cells(out: Path) -> dict:
    """The cells of a run, the last record of a key winning (as the experiment reads them)."""
    lines = (out / "cells.jsonl").read_text().splitlines()
    return {c["key"]: c["value"] for c in map(json.loads, lines)}


def test_mbrl_ensemble_killed_mid_episode_continues_to_the_same_run(lab_bin, tmp_path):
    """An ensemble (MVBx2) runs the loop and its plans carry the members' spread. Killed
    right after an episode's record and before its state (the least convenient instant), the
    run repeats the episode and ends with the records and members of the uninterrupted run."""
    args = ["mbrl", "--quick", "--models", "MVBx2"]
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    experiment(lab_bin, *args, "--out", str(whole))
    env = {**os.environ, "GRAYBOX_LAB_KILL_AFTER": "MVB×2/seed0/episode1"}
    p = subprocess.run([lab_bin, "experiment", *args, "--out", str(cut)], env=env,
                       capture_output=True, text=True, timeout=300)
    assert p.returncode != 0 and "stopping here" in p.stderr, p.stderr
    assert json.loads((cut / "state-MVBx2-seed0.json").read_text())["episodes_done"] == 0
    experiment(lab_bin, *args, "--out", str(cut))

    def same(record: dict) -> dict:
        timings = {"seconds", "plan_seconds", "train_seconds"}
        return {k: v for k, v in record.items() if k not in timings}

    def members(out: Path) -> list:
        state = json.loads((out / "state-MVBx2-seed0.json").read_text())
        return [m["params"] for m in state["checkpoint"]]

    a, b = cells(whole), cells(cut)
    keys = [f"MVB×2/seed0/episode{e}" for e in (1, 2)]
    for k in keys:
        assert same(a[k]) == same(b[k]), k
        assert a[k]["detail"]["spread"] > 0, "an ensemble's plan has a spread"
    assert len(members(whole)) == 2 and members(whole) == members(cut)
    assert "MVB×2" in (cut / "results.md").read_text()
    assert (cut / "scores-MVBx2.png").is_file() and (cut / "trajectories.png").is_file()


def test_a_run_cut_short_recomputes_only_its_missing_cells(lab_bin, tmp_path):
    out = tmp_path / "de"
    experiment(lab_bin, "data-efficiency", "--quick", "--out", str(out))
    md = (out / "results.md").read_text()
    lines = (out / "cells.jsonl").read_bytes().splitlines(keepends=True)
    # Killed while writing: the last cell lost, and half a line of the next one.
    (out / "cells.jsonl").write_bytes(b"".join(lines[:-1]) + lines[-1][:17])
    again = experiment(lab_bin, "data-efficiency", "--quick", "--out", str(out))
    now = (out / "cells.jsonl").read_bytes().splitlines(keepends=True)
    assert len(now) == len(lines), again.stderr
    assert all(line.endswith(b"\n") for line in now)
    assert json.loads(now[-1])["key"] == json.loads(lines[-1])["key"]
    # Cells are seeded: the recomputed one, and so the results, are the same.
    assert (out / "results.md").read_text() == md


def test_other_settings_in_the_same_out_are_refused(lab_bin, tmp_path):
    out = tmp_path / "de"
    experiment(lab_bin, "data-efficiency", "--quick", "--out", str(out))
    p = experiment(lab_bin, "data-efficiency", "--quick", "--seeds", "1", "--out", str(out),
                   ok=False)
    assert p.returncode == 2 and "seeds" in p.stderr and "--out" in p.stderr, p.stderr
    p = experiment(lab_bin, "rollout", "--quick", "--out", str(out), ok=False)
    assert p.returncode == 2 and "data-efficiency" in p.stderr, p.stderr


def test_bad_arguments_name_the_field(lab_bin, tmp_path):
    p = experiment(lab_bin, "data-efficiency", "--quick", "--models", "W-B,XYZ",
                   "--out", str(tmp_path / "x"), ok=False)
    assert p.returncode == 2 and "models" in p.stderr and "XYZ" in p.stderr, p.stderr
    p = experiment(lab_bin, "mbrl", "--quick", "--seeds", "0", "--out",
                   str(tmp_path / "y"), ok=False)
    assert p.returncode == 2 and "seeds" in p.stderr, p.stderr
    p = experiment(lab_bin, "mbrl", "--quick", "--lr=0", "--out", str(tmp_path / "y"), ok=False)
    assert p.returncode == 2 and "lr" in p.stderr, p.stderr
    p = experiment(lab_bin, "mbrl", "--quick", "--models", "MVBx1", "--out",
                   str(tmp_path / "y"), ok=False)
    assert p.returncode == 2 and "MVBx1" in p.stderr, p.stderr
    p = experiment(lab_bin, "multistep", "--quick", "--noise", "0.1", "--out",
                   str(tmp_path / "z"), ok=False)
    assert p.returncode == 2 and "noise" in p.stderr, p.stderr


def test_multistep_records_coarse_data_as_asked(lab_bin, tmp_path):
    """--dt and --substeps: the data recorded every Δt from RK4 at Δt/K, the trajectories as
    long in seconds as at the paper's step, both in run.json and said in results.md; at the
    paper's recording run.json stays as it was before the options (resumable old runs)."""
    out = tmp_path / "coarse"
    experiment(lab_bin, "multistep", "--quick", "--dt", "0.05", "--substeps", "50",
               "--out", str(out))
    s = json.loads((out / "run.json").read_text())["settings"]
    assert (s["dt"], s["substeps"]) == (0.05, 50), s
    assert (s["steps"], s["test_steps"]) == (6, 12), s  # 0.3 s and 0.6 s at 0.05 s
    md = (out / "results.md").read_text()
    assert "every Δt = 0.05 s" in md and "Δt / 50 = 0.001 s" in md, md
    paper = tmp_path / "paper"
    experiment(lab_bin, "multistep", "--quick", "--out", str(paper))
    s = json.loads((paper / "run.json").read_text())["settings"]
    assert "dt" not in s and "substeps" not in s and s["steps"] == 30, s
    p = experiment(lab_bin, "multistep", "--quick", "--substeps", "0", "--out",
                   str(tmp_path / "bad"), ok=False)
    assert p.returncode == 2 and "substeps" in p.stderr, p.stderr
