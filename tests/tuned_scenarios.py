"""Scenario copies that the tests and the campaign benchmarks share: imports nothing that sets up JAX (unlike
conftest.py, which sets the tests' XLA flags), so a benchmark can use it."""

from __future__ import annotations


def sbmpc_tuned_scenarios(folder, names=("head_on", "crossing_give_way", "overtaking")) -> list[str]:
    """Copies of built-in river-scale scenarios that give ``mpc.sbmpc: {preset: river}`` (so the ``sbmpc`` method,
    whose defaults were tuned for 30 m ships at 9 m/s, fits their 5 m boats), written into ``folder``; their
    paths, in the order of ``names``."""
    import pathlib

    import yaml

    from psbmpc_jax.scenario.schema import SCENARIO_DIR

    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for name in names:
        data = yaml.safe_load((SCENARIO_DIR / f"{name}.yaml").read_text())
        data["mpc"]["sbmpc"] = {"preset": "river"}
        path = folder / f"{name}.yaml"
        path.write_text(yaml.safe_dump(data, sort_keys=False))
        paths.append(str(path))
    return paths
