"""tools/audit_surfaces.py classifies what it sees: a refusal naming the field is an error, one that does not is
unclear, an accepted wrong result is silent, a raw exception or a process killed for memory is a crash, a case
past its timeout a runaway; the record is never written over.  Synthetic cases (each a small child process)."""

from __future__ import annotations

import importlib.util
import pathlib
import tempfile

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("audit_surfaces", ROOT / "tools" / "audit_surfaces.py")
audit = importlib.util.module_from_spec(spec)
spec.loader.exec_module(audit)


def outcome(code: str, match: str | None = None, timeout: float = 60.0, memory: int = 2 ** 30) -> dict:
    case = audit.C("synthetic", "test", "synthetic", code, match=match)
    return audit.run_case(case, memory, timeout, pathlib.Path(tempfile.gettempdir()))


@pytest.mark.parametrize("code, match, expected", [
    ("def case(tmp):\n    raise ValueError('x.y must be > 0, got -1')\n", r"x\.y must be > 0", "error"),
    ("def case(tmp):\n    raise ValueError('something went wrong')\n", r"x\.y must be > 0", "unclear"),
    ("def case(tmp):\n    return accepted('took -1')\n", None, "silent"),
    ("def case(tmp):\n    return dict(kind='result', ok=True, detail='right')\n", None, "correct"),
    ("def case(tmp):\n    raise KeyError('raw')\n", None, "crash"),
    ("def case(tmp):\n    return cli_outcome(1, '', 'Traceback (most recent call last):')\n", None, "crash"),
    ("def case(tmp):\n    return bytearray(8 * 2 ** 30)\n", None, "crash"),            # past the address space
])
def test_outcomes(code, match, expected):
    r = outcome(code, match)
    assert r["outcome"] == expected, r


def test_runaway():
    r = outcome("def case(tmp):\n    import time\n    time.sleep(60)\n", timeout=3.0)
    assert r["outcome"] == "runaway" and "did not finish in 3 s" in r["detail"]


def test_every_case_has_a_pattern_or_checks_a_result_and_the_record_is_not_overwritten(tmp_path, capsys):
    for c in audit.CASES:
        assert c["match"] or "kind=\"result\"" in c["code"], c["name"]
    assert len({c["name"] for c in audit.CASES}) == len(audit.CASES)
    existing = tmp_path / "audit.json"
    existing.write_text("{}")
    with pytest.raises(SystemExit):
        audit.main(["--cases", "n_ps_101", "--json", str(existing)])
    assert existing.read_text() == "{}" and "never overwrites" in capsys.readouterr().err
