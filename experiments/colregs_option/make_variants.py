"""Write a COLREGS-option copy of shipped scenarios: the same file with ``mpc.colregs_option`` added (and the
name suffixed ``_colregs``), so paper-faithful and option runs differ in that section only.

    PYTHONPATH=. python experiments/colregs_option/make_variants.py OUT_DIR SCENARIO... [--set key=value ...]
"""

from __future__ import annotations

import argparse
import pathlib

import yaml

from psbmpc_jax.safe_io import atomic_write_text
from psbmpc_jax.scenario.load import builtin_path


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("scenarios", nargs="+")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a mpc.colregs_option field (YAML value), e.g. act_range_radii=3.5")
    a = ap.parse_args(argv)
    option = {"enabled": True}
    for kv in a.set:
        key, sep, value = kv.partition("=")
        if not sep:
            raise SystemExit(f"--set {kv!r}: expected KEY=VALUE")
        option[key] = yaml.safe_load(value)
    out = pathlib.Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    for name in a.scenarios:
        d = yaml.safe_load(builtin_path(name).read_text())
        d["name"] = f"{d['name']}_colregs"
        d.setdefault("mpc", {})["colregs_option"] = dict(option)
        atomic_write_text(out / f"{name}_colregs.yaml", yaml.safe_dump(d, sort_keys=False))
        print(out / f"{name}_colregs.yaml")


if __name__ == "__main__":
    main()
