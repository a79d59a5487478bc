"""Library messages go to ``logging`` (never to stdout), the CLI routes them (-v / -q) and -q turns off progress;
no bare print() in the library outside the command-line modules."""

from __future__ import annotations

import ast
import logging
import pathlib

import pytest
import yaml

from psbmpc_jax.apps.cli import _with_default_subcommand, main
from psbmpc_jax.scenario import scenario_from_dict
from psbmpc_jax.sim import simulate

ROOT = pathlib.Path(__file__).resolve().parents[1]
PKG = ROOT / "psbmpc_jax"
#: Modules that are command lines: they print their results.
CLI_MODULES = {"apps", "evaltool/cli.py"}

#: A short closed loop with one behaviour (a quick compile): 4 MPC updates, 2 runs.
SCENARIO = {"name": "quiet", "simulation": {"dt_s": 0.5, "duration_s": 20}, "monte_carlo": {"runs": 2, "seed": 3},
            "mpc": {"preset": "nidelva", "update_period_s": 5, "speed_factors": [[1.0, 0.0]],
                    "course_offsets_deg": [[0]]},
            "own_ship": {"name": "OS", "position_m": [0, 0], "course_deg": 0, "speed_mps": 2,
                         "waypoints_m": [[0, 0], [150, 0]]},
            "targets": [{"name": "TS1", "position_m": [100, 50], "course_deg": 180, "speed_mps": 2,
                         "colav": "none"}]}


def _prints_outside_main(path: pathlib.Path) -> list[int]:
    """Lines of print() calls outside ``if __name__ == "__main__":`` blocks and functions named ``main`` (the
    ``python -m`` entry points of a module)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    allowed = set()
    for node in ast.walk(tree):
        is_main_block = (isinstance(node, ast.If) and isinstance(node.test, ast.Compare)
                         and isinstance(node.test.left, ast.Name) and node.test.left.id == "__name__")
        if is_main_block or (isinstance(node, ast.FunctionDef) and node.name == "main"):
            allowed |= {id(n) for n in ast.walk(node)}
    return [n.lineno for n in ast.walk(tree) if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)
            and n.func.id == "print" and id(n) not in allowed]


def test_no_bare_print_in_the_library():
    found = {}
    for path in PKG.rglob("*.py"):
        rel = path.relative_to(PKG).as_posix()
        if rel.split("/")[0] in CLI_MODULES or rel in CLI_MODULES:
            continue
        lines = _prints_outside_main(path)
        if lines:
            found[rel] = lines
    assert found == {}, f"print() in library modules (use logging.getLogger(__name__)): {found}"


def test_the_print_scan_finds_a_print(tmp_path):
    p = tmp_path / "m.py"
    p.write_text("def f():\n    print('x')\n\ndef main():\n    print('ok')\n\nif __name__ == '__main__':\n"
                 "    print(main())\n")
    assert _prints_outside_main(p) == [2]


def test_simulate_writes_nothing_and_logs(capsys, caplog):
    with caplog.at_level(logging.INFO, logger="psbmpc_jax"):
        result = simulate(scenario_from_dict(SCENARIO), progress=False)
    assert result.states.shape[0] == 2
    out = capsys.readouterr()
    assert out.out == "" and out.err == ""
    msgs = [r.getMessage() for r in caplog.records if r.name == "psbmpc_jax.sim.simulator"]
    assert msgs[0] == "quiet (2 runs): 4 MPC updates; the first compiles the solver"
    assert msgs[1].startswith("quiet (2 runs): first update (compiling) took ")
    assert msgs[-1].startswith("quiet (2 runs): 4 of 4 MPC updates in ")


@pytest.fixture(scope="module")
def scenario_file(tmp_path_factory):
    p = tmp_path_factory.mktemp("sc") / "quiet.yaml"
    p.write_text(yaml.safe_dump(SCENARIO), encoding="utf-8")
    return p


@pytest.mark.parametrize("flags, progress, info", [
    ([], True, False),                       # the default: a progress bar, warnings only
    (["-v"], True, True),                    # -v: the library's information too
    (["-q"], False, False),                  # -q before the subcommand: no progress
    (["--quiet"], False, False),
])
def test_cli_quiet_and_verbose(scenario_file, tmp_path, capsys, flags, progress, info):
    args = [*flags, "run", str(scenario_file), "--no-figures", "--out", str(tmp_path / "out")]
    assert main(args) == 0
    out = capsys.readouterr()
    assert ("update/s" in out.err or "s/update" in out.err) == progress, out.err    # tqdm's rate: the bar
    assert ("psbmpc-jax: INFO: quiet (2 runs): 4 MPC updates" in out.err) == info, out.err
    assert "psbmpc-jax run: 1 scenario, 2 runs" in out.out                  # results are printed even with -q
    if flags == ["-q"]:
        assert out.err == ""


def test_run_quiet_flag_after_the_subcommand(scenario_file, tmp_path, capsys):
    assert main(["run", str(scenario_file), "--no-figures", "--quiet", "--out", str(tmp_path / "o")]) == 0
    assert capsys.readouterr().err == ""


def test_main_restores_the_callers_logging(scenario_file, tmp_path):
    logger = logging.getLogger("psbmpc_jax")
    before = (logger.level, list(logger.handlers))
    main(["-vv", "evaluate", str(tmp_path / "missing.csv")])
    assert (logger.level, list(logger.handlers)) == before


def test_global_flags_before_the_default_subcommand():
    assert _with_default_subcommand([]) == ["example"]
    assert _with_default_subcommand(["-q"]) == ["-q", "example"]
    assert _with_default_subcommand(["-v", "--n-m", "1"]) == ["-v", "example", "--n-m", "1"]
    assert _with_default_subcommand(["-q", "run", "head_on"]) == ["-q", "run", "head_on"]
    assert _with_default_subcommand(["--n-m", "1"]) == ["example", "--n-m", "1"]
