"""README.md, as written, works: its curl walkthrough, its command-line example, its Python
example and its robot example run verbatim (the fenced blocks tagged `readme-test:<name>`,
the blocks of one name as one script, in order) against the release binary, and what the
README says they print holds. Every shell block is tagged: `readme-test:<name>`, or
`readme-skip: <why>` (a command that never exits, needs a container engine, or names
placeholder hosts), and no command hides in an indented block.

The walkthroughs take the service's address from GRAYBOX_HTTP / GRAYBOX_GRPC as the README
says; the test sets those to its own server's free ports.
"""

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import serve

ROOT = Path(__file__).resolve().parents[2]
FENCE = re.compile(r"^```(\w+) readme-test:(\w+)\n(.*?)^```$", re.S | re.M)
ANY_FENCE = re.compile(r"^```(.*?)\n(.*?)^```$", re.S | re.M)
SHELLS = {"sh", "bash", "shell", "console", "zsh"}
# The first word of a command a reader would run (an indented line starting so is a shell
# block without a fence, hence without a tag).
COMMAND = re.compile(r"^ {4,}(cargo|graybox|graybox-lab|python3?|\.venv/|curl|docker|bash|"
                     r"export|cd|target/|pip|openssl) ", re.M)


def blocks(name: str) -> tuple[str, str]:
    """The language and the joined text of the README's blocks tagged readme-test:<name>."""
    found = [(lang, body) for lang, tag, body in FENCE.findall((ROOT / "README.md").read_text())
             if tag == name]
    assert found, f"README.md has no block tagged readme-test:{name}"
    langs = {lang for lang, _ in found}
    assert len(langs) == 1, langs
    return langs.pop(), "\n".join(body for _, body in found)


def run_sh(script: str, env: dict, timeout: float) -> subprocess.CompletedProcess:
    """A README shell block as a reader runs it: bash from the repository root, stopping at the
    first failing command."""
    return subprocess.run(["bash", "-euo", "pipefail", "-c", script], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=timeout)


def reader_env(**extra) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith("GRAYBOX_")}
    env.update(extra)
    return env


def json_lines(text: str) -> list:
    out = []
    for line in text.splitlines():
        try:
            out.append(json.loads(line))
        except ValueError:
            pass
    return out


@pytest.fixture(scope="module")
def walkthrough(graybox_bin, tmp_path_factory):
    """The service started as the README's first command would, then the curl walkthrough."""
    assert Path(graybox_bin).resolve() == (ROOT / "target/release/graybox").resolve(), \
        "the README runs target/release/graybox: test that binary"
    tmp = tmp_path_factory.mktemp("readme")
    with serve(graybox_bin, tmp, "--workers", "1", name="graybox serve (README)") as s:
        env = reader_env(GRAYBOX_HTTP=f"127.0.0.1:{s.http_port}", GRAYBOX_GRPC=s.grpc_target)
        _, script = blocks("curl")
        # Expose what the walkthrough set, for the checks and the Python example.
        done = run_sh(script + '\necho "README-TEST MODEL=$MODEL JOB=$JOB WORK=$WORK"',
                      env, timeout=600)
        yield s, env, done


def test_curl_walkthrough(walkthrough):
    s, _, done = walkthrough
    assert done.returncode == 0, f"stdout:\n{done.stdout}\nstderr:\n{done.stderr}"
    ids = dict(kv.split("=", 1) for kv in done.stdout.strip().splitlines()[-1].split()[1:])
    status, job = s.rest.get(f"/v1/jobs/{ids['JOB']}")
    assert status == 200 and job["state"] == "succeeded", job
    assert job["model_id"] == ids["MODEL"]
    # Its claim: `graybox eval` on the validation file gives the job's best_val_loss.
    evals = [j for j in json_lines(done.stdout) if isinstance(j, dict) and "loss" in j]
    assert evals, done.stdout
    assert evals[-1]["loss"] == pytest.approx(job["best_val_loss"], rel=1e-5)
    # Its model print ends in a newline (the next output does not run on).
    models = [j for j in json_lines(done.stdout) if isinstance(j, dict) and j.get("id") == ids["MODEL"]]
    assert models and models[0]["metrics"]["best_val_loss"] == job["best_val_loss"]
    # The CSV and trajectory uploads were stored, with no warnings on this clean data.
    names = {d["name"]: d for d in s.rest.get("/v1/datasets")[1]["items"]}
    assert names["pend-csv"]["count"] == 2 and names["pend-traj"]["count"] == 2, names
    assert all(d["warnings"] == [] for d in names.values()), names
    # The scratch directory, not the repository, got the files.
    assert Path(ids["WORK"], "mvf.gbx").is_file()
    assert not (Path(__file__).resolve().parents[2] / "mvf.gbx").exists()


def test_python_example(walkthrough):
    """The Python section as a reader runs it after the walkthrough: a venv, the client
    installed into it, the REST example training from Python, the gRPC example tracking a
    swing with the walkthrough's model; the gRPC example shown is the file it runs."""
    _, env, done = walkthrough
    assert done.returncode == 0, done.stderr
    ids = dict(kv.split("=", 1) for kv in done.stdout.strip().splitlines()[-1].split()[1:])
    lang, shown = blocks("client")
    assert lang == "python"
    assert shown.strip() == (ROOT / "examples/python/track_swing.py").read_text().strip()
    _, script = blocks("python")
    path = f"{ROOT / 'target/release'}{os.pathsep}{env['PATH']}"
    r = subprocess.run(["bash", "-euo", "pipefail", "-c", script], cwd=ids["WORK"],
                       env={**env, "MODEL": ids["MODEL"], "WORK": ids["WORK"], "REPO": str(ROOT),
                            "PATH": path, "EPOCHS": "6"},
                       capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, f"stdout:\n{r.stdout}\nstderr:\n{r.stderr}"
    out = r.stdout
    # REST: trained from Python with its progress shown, evaluated, saved, a refusal named.
    assert "MVF, 10-step windows: succeeded" in out, out
    # Which loss is which: best_val_loss is over 10-step windows and says so; the progress
    # lines name each loss by what it is over, the train loss switching from one step to the
    # windows halfway (a line says so, where its figure jumps); and the training checks
    # compare it with q̈ = 0 over the same windows (it was held against the one-step bar and
    # every multi-step run "learned nothing").
    trains = re.findall(r"^epoch \d+: train \((1-step|10-step windows)\) ", r.stderr, re.M)
    assert trains == ["1-step"] * 3 + ["10-step windows"] * 3, r.stderr
    assert "-- epoch 4: the train loss is now over 10-step windows" in r.stderr, r.stderr
    assert re.search(r"best val loss [\d.]+ over 10-step windows", out), out
    assert r.stderr.count(", val (10-step windows) ") == 6, r.stderr
    assert "learned nothing" not in out, out
    assert re.search(r"after 1\.0 s: median \|q̂ − q\| [\d.]+ rad", out), out
    assert Path(ids["WORK"], "mvf-windows.gbx").is_file()
    assert "refused: 422 training.epochs must be between" in out, out
    # gRPC: TVLQR brings the perturbed start back to the swing, open loop does not.
    assert f"model {ids['MODEL']}: nq = 2, nv = 2, m = 2" in out, out
    # Then in process with graybox_native, the loop closed a step at a time: the same.
    loops = re.findall(r"open loop ([\d.]+), TVLQR ([\d.]+)", out)
    assert len(loops) == 2, out
    for open_loop, tvlqr in loops:
        assert float(tvlqr) < 0.5 * float(open_loop), out
    assert "refused: INVALID_ARGUMENT" in out, out
    assert "model file: nq = 2, nv = 2, m = 2" in out, out
    assert "refused: INVALID_ARGUMENT x" in out, out


def test_command_line_example(graybox_bin):
    lang, script = blocks("cli")
    assert lang == "sh"
    done = run_sh(script + '\necho "README-TEST WORK=$PWD"', reader_env(), timeout=900)
    assert done.returncode == 0, f"stdout:\n{done.stdout}\nstderr:\n{done.stderr}"
    work = Path(done.stdout.strip().splitlines()[-1].split("=", 1)[1])
    report = json.loads((work / "mvf-report.json").read_text())
    assert report["epochs"] == 50 and len(report["history"]) == 50
    # stdout's report is one JSON object without the history.
    wb = json.loads((work / "wb-report.json").read_text())
    assert "history" not in wb and wb["model"] == "W-B", wb
    evals = [j for j in json_lines(done.stdout) if isinstance(j, dict) and "loss" in j]
    assert evals and evals[0]["count"] == 1024
    # W-B identifies the ratios the README lists.
    inspected = [j for j in json.loads("[" + _objects(done.stdout) + "]")
                 if "identifiable" in j and j.get("template") == "double_pendulum"]
    names = {c["name"] for c in inspected[-1]["identifiable"]}
    assert {"m1/m2", "l1/l2", "g/l1"} <= names, names
    # The robot-log example: the committed log imports as two trajectories on its samples' own
    # times with velocities estimated, and W-B from g = 7 recovers the logged pendulum
    # (measured: g/l 9.91, b/(ml²) 0.96; the estimated velocities and the inputs' step means
    # bias them slightly).
    imported = [j for j in json.loads("[" + _objects(done.stdout) + "]") if "import" in j]
    assert imported and imported[0]["import"]["trajectories"] == 2, imported
    assert imported[0]["import"]["velocities"] == "estimated"
    assert imported[0]["import"]["times"] == "samples"
    pendulum = [j for j in json.loads("[" + _objects(done.stdout) + "]")
                if "identifiable" in j and j.get("template") == "pendulum"]
    combos = {c["name"]: c["value"] for c in pendulum[-1]["identifiable"]}
    assert abs(combos["g/l"] - 10) < 0.1 and abs(combos["b/(m*l^2)"] - 1) < 0.1, combos
    # The formula-template example trains W-B on the cart-pole from its document.
    assert '"name":"cartpole"' in (work / "m.gbx").read_text().replace(" ", "")
    # The Control example: the swing-up on the true double pendulum reaches the top.
    plan = json.loads((work / "swing-up.json").read_text())
    assert plan["goal_error"] < 0.1 and len(plan["u"]) == 21, plan["goal_error"]
    assert all(abs(u) <= 120 for row in plan["u"] for u in row)
    assert all(b <= a for a, b in zip(plan["costs"], plan["costs"][1:]))
    # The UR5 reach converges within the URDF's effort limits, the bounds the plan reports.
    reach = json.loads((work / "reach.json").read_text())
    assert reach["converged"] and len(reach["u"]) == 100, reach["goal_error"]
    assert all(abs(u) <= m for row in reach["u"] for u, m in zip(row, reach["u_max"]))


def _objects(text: str) -> str:
    """The top-level JSON objects printed (pretty or not) in `text`, comma-joined."""
    objs, depth, start = [], 0, None
    for i, ch in enumerate(text):
        if ch == "{":
            if depth == 0:
                start = i
            depth += 1
        elif ch == "}" and depth:
            depth -= 1
            if depth == 0:
                objs.append(text[start:i + 1])
    return ",".join(objs)


def test_every_serve_flag_is_in_the_readme_table(graybox_bin):
    """The flag table lists every flag `graybox serve --help` shows, with its variable and
    its default."""
    help_text = subprocess.run([graybox_bin, "serve", "--help"], capture_output=True,
                               text=True, check=True).stdout
    readme = (ROOT / "README.md").read_text()
    table = {}
    for line in readme.splitlines():
        m = re.match(r"\| `(--[a-z-]+)[^|]*\| `?(GRAYBOX_\w+)", line)
        if m:
            table[m.group(1)] = line
            for extra in re.findall(r"`(--[a-z-]+)", line)[1:]:
                table[extra] = line
    flags = re.findall(r"^\s+(--[a-z][a-z-]*)", help_text, re.M)
    assert len(flags) >= 20, help_text
    for flag in flags:
        if flag == "--help":
            continue
        assert flag in table, f"{flag} is not in README's flag table"
        entry = help_text[help_text.index(flag):].split("\n      --", 1)[0]
        env = re.search(r"\[env: (\w+)", entry)
        assert env and env.group(1) in table[flag], (flag, table[flag])
        default = re.search(r"\[default: ([^\]]+)\]", entry)
        if default:
            assert default.group(1).split()[0] in table[flag], (flag, default.group(1), table[flag])


def test_every_shell_block_is_tagged_to_run_or_skip():
    """A shell block the test does not run must say why; an untagged one (or a command in an
    indented block, which cannot carry a tag) fails, so a new walkthrough is run or excused."""
    readme = (ROOT / "README.md").read_text()
    untagged = []
    for info, body in ANY_FENCE.findall(readme):
        lang, _, tag = info.partition(" ")
        if lang not in SHELLS and lang != "":
            continue
        run = re.fullmatch(r"readme-test:\w+", tag)
        skip = re.fullmatch(r"readme-skip: \S.{5,}", tag)
        if not (run or skip):
            untagged.append(f"```{info}\n{body.splitlines()[0] if body else ''}")
    outside = ANY_FENCE.sub("", readme)
    untagged += [f"indented: {m.group(0).strip()}" for m in COMMAND.finditer(outside)]
    assert not untagged, "README shell blocks without readme-test:/readme-skip: " + \
        "\n".join(untagged)


def test_the_robot_example_runs_as_written(walkthrough):
    """The URDF example's block, verbatim from the repository with the service running and
    nothing else set up (no graybox on PATH: the script finds the build), shortened by EPOCHS
    as the README says; it identifies the arm and writes the robot where it says."""
    _, env, done = walkthrough
    assert done.returncode == 0, done.stderr
    lang, script = blocks("urdf")
    assert lang == "sh"
    bare = os.pathsep.join(p for p in env["PATH"].split(os.pathsep)
                           if not Path(p, "graybox").exists())
    r = run_sh(script, {**env, "PATH": bare, "EPOCHS": "3"}, timeout=900)
    assert r.returncode == 0, f"stdout:\n{r.stdout}\nstderr:\n{r.stderr}"
    assert "| upper_arm.mass | 1.500 | 1.950 |" in r.stdout, r.stdout
    written = re.search(r"(/\S+/identified_arm\.urdf)", r.stdout + r.stderr)
    assert written and Path(written.group(1)).is_file(), r.stdout
    assert "too stiff" not in r.stderr, r.stderr
