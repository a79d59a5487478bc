"""Generate COLREGS-typed encounters as scenario files: the same as ``psbmpc-jax generate`` (its options and
behaviour live in :mod:`psbmpc_jax.apps.generate`).

    python tools/generate_encounters.py head_on --count 20 --seed 0 --out generated/head_on
    python tools/generate_encounters.py head_on crossing_give_way --count 5 --seed 1 --out generated/two
    python tools/generate_encounters.py overtaking --count 10 --seed 0 --out generated/fjord \\
        --chart-builtin trondheim --chart-clip-m 1000 --own-north 300 1900 --own-east -1500 7000 --check
"""

from __future__ import annotations

import argparse
import logging
import sys

from psbmpc_jax.apps.generate import USER_ERRORS, add_generate_arguments, run


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="generate_encounters", description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    add_generate_arguments(ap)
    return ap


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        return run(args)
    except USER_ERRORS as exc:
        print(f"generate_encounters: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
