"""SIGKILL of ``psbmpc-jax evaluate`` at random moments never leaves a mix of two evaluations.

``evaluate --out scores.json`` writes one file atomically (a temporary ``.<name>.<random>.tmp`` renamed over it);
``evaluate --explain --out FOLDER`` writes a run folder (staged, the manifest last; :mod:`psbmpc_jax.runfolder`).
After each kill the output is the previous complete result or the new complete result, equal to what an
uninterrupted run of either writes (the explanation folder: or a manifest marked incomplete, which every reader
refuses, as for ``run``).  Two kinds of kill:

* the evaluate process killed at a seeded random step of writing its output (every file-system operation on the
  output's folder, every write to a file there, the moment after such a file was opened; ``KILLER``), the first
  and the last step always among them -- for the scores file and for the explanation folder;
* the command itself (``python -m psbmpc_jax.apps.cli evaluate``) killed at a random moment of its run.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
from conftest import run_cli as conftest_run_cli

from psbmpc_jax.runfolder import RunFolderError, read_manifest, verify_member
from psbmpc_jax.safe_io import TEMP_SUFFIX

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: Two track files of different content: a head-on of two vessels, and three vessels.
TRACKS_A = "t_s,vessel,north_m,east_m\n" + "".join(f"{t},own,{t},0\n{t},ferry,{200 - t},5\n" for t in range(0, 200, 2))
TRACKS_B = "t_s,vessel,north_m,east_m\n" + "".join(
    f"{t},own,{t},0\n{t},ferry,{300 - t},-8\n{t},tug,{t * 0.5},{150 - t * 0.5}\n" for t in range(0, 300, 2))


def run_cli(argv) -> int:
    return conftest_run_cli(argv)[0]


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """The two track files and the output of an uninterrupted run of each (scores file and explanation)."""
    base = tmp_path_factory.mktemp("evalkill")
    a, b = base / "a.csv", base / "b.csv"
    a.write_text(TRACKS_A)
    b.write_text(TRACKS_B)
    ref = {}
    for name, path in (("a", a), ("b", b)):
        assert run_cli(["evaluate", str(path), "--out", str(base / f"{name}.json")]) == 0
        assert run_cli(["evaluate", str(path), "--explain", "--out", str(base / f"{name}_explain")]) == 0
        ref[name] = (json.loads((base / f"{name}.json").read_text()),
                     json.loads((base / f"{name}_explain" / "explain.json").read_text()),
                     set(read_manifest(base / f"{name}_explain")["files"]))
    assert ref["a"][0] != ref["b"][0] and ref["a"][1] != ref["b"][1] and ref["a"][2] != ref["b"][2]
    return a, b, ref


def scores_state(out, ref) -> str:
    """Which complete result the scores file holds ("a" or "b"); anything else fails.  Beside it only the
    atomic writer's temporary files may be left by a kill (never read: they are not ``out``)."""
    doc = json.loads(out.read_text())
    state = next((k for k, v in ref.items() if doc == v[0]), None)
    assert state is not None, "the scores file is neither complete result"
    left = {p.name for p in out.parent.iterdir()} - {out.name}
    assert all(n.startswith(f".{out.name}.") and n.endswith(TEMP_SUFFIX) for n in left), left
    return state


def explain_state(folder, ref) -> str:
    """"a", "b" (a complete run folder equal to that run's output, every file verified against the manifest)
    or "incomplete" (the manifest says so and the readers refuse every file)."""
    doc = read_manifest(folder)
    if not doc["complete"]:
        for name in doc["files"] or ["explain.json"]:
            with pytest.raises(RunFolderError, match="did not complete"):
                verify_member(folder / name)
        return "incomplete"
    for name in doc["files"]:
        assert verify_member(folder / name) == doc
    data = json.loads((folder / "explain.json").read_text())
    state = next((k for k, v in ref.items() if data == v[1] and set(doc["files"]) == v[2]), None)
    assert state is not None, "the explanation folder is neither complete result"
    return state


#: The evaluate process, killed with SIGKILL at its K-th step of writing into the output's folder (0: never; the
#: number of steps is printed at the end).  Steps: every file-system operation there seen by an audit hook
#: (opening a file, creating a temporary file or folder, renaming, removing, chmod; the kill comes before the
#: operation), the moment right after a file there was opened for writing (truncated, nothing written yet), and
#: before each write to and the close of such a file.
KILLER = textwrap.dedent("""
    import builtins, contextlib, io, os, signal, sys
    sys.path.insert(0, sys.argv[1])
    K, TARGET, argv = int(sys.argv[2]), os.path.abspath(sys.argv[3]), sys.argv[4:]
    EVENTS = {"open", "os.rename", "os.remove", "os.rmdir", "os.mkdir", "os.chmod", "shutil.rmtree",
              "shutil.move", "tempfile.mkstemp", "tempfile.mkdtemp"}
    n = 0
    temp_in_target = False

    def inside(p):
        return isinstance(p, (str, bytes, os.PathLike)) and os.path.abspath(os.fsdecode(p)).startswith(TARGET)

    def step():
        global n
        n += 1
        if n == K:
            os.kill(os.getpid(), signal.SIGKILL)

    def hook(event, args):
        global temp_in_target
        if event in EVENTS and args:
            paths = [args[0]] + ([args[1]] if event == "os.rename" else [])
            if any(inside(p) for p in paths):
                if event == "tempfile.mkstemp":
                    temp_in_target = True
                step()

    class Writing:
        def __init__(self, fh):
            self._fh = fh
        def write(self, data):
            step()
            return self._fh.write(data)
        def close(self):
            step()
            return self._fh.close()
        def __enter__(self):
            return self
        def __exit__(self, *exc):
            step()
            return self._fh.__exit__(*exc)
        def __iter__(self):
            return iter(self._fh)
        def __getattr__(self, name):
            return getattr(self._fh, name)

    real_open = io.open

    def open_(file, mode="r", *args, **kwargs):
        fh = real_open(file, mode, *args, **kwargs)
        writing = any(c in mode for c in "wax+")
        if writing and (inside(file) or (isinstance(file, int) and temp_in_target)):
            step()
            return Writing(fh)
        return fh

    builtins.open = io.open = open_
    from psbmpc_jax.apps.cli import main
    sys.addaudithook(hook)
    with contextlib.redirect_stdout(io.StringIO()):
        rc = main(argv)
    print("events", n, "rc", rc)
""")


def killed_at_events(argv_old: list, argv_new: list, target, picks: int, seed: int, check) -> list:
    """Write the previous result (``evaluate argv_old``), then run ``evaluate argv_new`` in a process killed at
    its k-th file-system event on ``target`` (the hook runs before the event's operation; k: ``picks`` seeded
    random draws over all its events, always including the first and the last); ``check()`` the output after
    each kill.  Returns the states seen: first that of an uninterrupted run, then one per kill (k ascending)."""
    def run(k: int) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-c", KILLER, ROOT, str(k), str(target), *argv_new], cwd=ROOT,
                              capture_output=True, timeout=120)

    assert run_cli(argv_old) == 0
    full = run(0)
    assert full.returncode == 0, full.stderr.decode()
    n_events = int(full.stdout.split()[-3])
    assert n_events >= 2, full.stdout
    states = [check()]                                                  # uninterrupted: the new result
    rng = np.random.default_rng(seed)
    ks = sorted({1, n_events} | {int(k) for k in rng.integers(1, n_events + 1, size=picks)})
    for k in ks:
        assert run_cli(argv_old) == 0                                   # the previous result, complete
        proc = run(k)
        assert proc.returncode == -9, (k, proc.returncode, proc.stderr.decode()[-2000:])
        states.append(check())
    return states


def test_sigkill_at_random_steps_of_writing_the_scores_file(inputs, tmp_path):
    """``evaluate b.csv --out scores.json`` over a complete result of a.csv: killed at its first, its last and
    seeded random steps of writing (``KILLER``), the file is a's result or b's, never anything else."""
    a, b, ref = inputs
    out = tmp_path / "out" / "scores.json"
    out.parent.mkdir()
    states = killed_at_events(["evaluate", str(a), "--out", str(out)], ["evaluate", str(b), "--out", str(out)],
                              out.parent, picks=4, seed=27, check=lambda: scores_state(out, ref))
    print("scores file: states after the kills", states)
    assert states[0] == "b" and set(states[1:]) == {"a"}, states    # the rename is the last step: before it, a


def test_sigkill_at_random_steps_of_writing_the_explanation_folder(inputs, tmp_path):
    a, b, ref = inputs
    folder = tmp_path / "explain"
    states = killed_at_events(["evaluate", str(a), "--explain", "--out", str(folder), "--force"],
                              ["evaluate", str(b), "--explain", "--out", str(folder), "--force"],
                              tmp_path, picks=2, seed=28, check=lambda: explain_state(folder, ref))
    print("explanation folder: states after the kills", states)
    assert states[0] == "b" and states[1] == "a" and set(states) <= {"a", "b", "incomplete"}, states
    # after any kill the next evaluate writes a complete folder again
    assert run_cli(["evaluate", str(b), "--explain", "--out", str(folder), "--force"]) == 0
    assert explain_state(folder, ref) == "b"


def test_sigkill_of_the_command_at_random_moments(inputs, tmp_path):
    """The command line itself: ``evaluate b.csv --out scores.json`` over a complete result of a.csv, killed at
    a random moment of its run (its duration measured here first)."""
    a, b, ref = inputs
    out = tmp_path / "scores.json"
    cmd = [sys.executable, "-m", "psbmpc_jax.apps.cli", "evaluate", str(b), "--out", str(out)]
    t0 = time.perf_counter()
    done = subprocess.run(cmd, cwd=ROOT, capture_output=True)
    duration = time.perf_counter() - t0
    assert done.returncode == 0, done.stderr.decode()
    assert scores_state(out, ref) == "b"
    rng = np.random.default_rng(29)
    states = []
    for _ in range(3):
        assert run_cli(["evaluate", str(a), "--out", str(out)]) == 0          # the previous result
        proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(float(rng.uniform(0.2, 1.1)) * duration)
        proc.kill()
        proc.wait(timeout=60)
        states.append(scores_state(out, ref))
    assert set(states) <= {"a", "b"}
