"""The simulation progress bar: one tick per MPC update, ETA from the updates after the compiling first one,
tqdm when installed (a stub here), the plain bar otherwise."""

from __future__ import annotations

import io
import sys
import types

import pytest

import psbmpc_jax.sim.simulator as simulator


class Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


@pytest.fixture
def clock(monkeypatch):
    c = Clock()
    monkeypatch.setattr(simulator.time, "perf_counter", c)
    return c


@pytest.fixture
def no_tqdm(monkeypatch):
    monkeypatch.setitem(sys.modules, "tqdm", None)     # import tqdm -> ImportError


def test_eta_ignores_the_compiling_first_update(clock, no_tqdm, monkeypatch):
    err = io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    bar = simulator._Progress(8, "case (2 runs)", True)
    assert bar.eta() is None
    clock.now += 30.0                 # first update: compile
    bar.update(1)
    assert bar.eta() is None          # one tick says nothing about the rate
    clock.now += 2.0
    bar.update(2)
    clock.now += 2.0
    bar.update(3)
    assert bar.eta() == pytest.approx(2.0 * 5)          # 2 s per update after the first, 5 left (not 30+)
    for k in range(4, 9):
        clock.now += 2.0
        bar.update(k)
    assert bar.eta() == 0.0
    bar.close()
    lines = err.getvalue().splitlines()                 # a log file: the start, then every 25 %
    assert lines[0].startswith("case (2 runs) [") and "0/8 MPC updates" in lines[0] and "compiles" in lines[0]
    assert [ln.split("]")[1].split()[0] for ln in lines[1:]] == ["2/8", "4/8", "6/8", "8/8"]
    assert "~8 s left" in lines[2] and lines[-1].endswith("~0 s left")


def test_disabled_bar_writes_nothing(clock, no_tqdm, monkeypatch):
    err = io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    bar = simulator._Progress(3, "x", False)
    for k in (1, 2, 3):
        bar.update(k)
    bar.close()
    assert err.getvalue() == ""


def test_tqdm_used_when_installed(clock, monkeypatch):
    made = []

    class FakeTqdm:
        def __init__(self, total, **kw):
            self.total, self.kw, self.n, self.initial, self.last_print_n = total, kw, 0, 0, 0
            self.events = []
            made.append(self)

        def set_postfix_str(self, s, refresh=True):
            self.events.append(("postfix", s))

        def reset(self, total=None):
            self.n = 0
            self.events.append(("reset", total))

        def refresh(self):
            self.events.append(("refresh", self.n))

        def update(self, n):
            self.n += n
            self.events.append(("update", n))

        def close(self):
            self.events.append(("close",))

    monkeypatch.setitem(sys.modules, "tqdm", types.SimpleNamespace(tqdm=FakeTqdm))
    bar = simulator._Progress(4, "case", True)
    clock.now += 10.0
    for k in (1, 2, 3, 4):
        bar.update(k)
        clock.now += 1.0
    bar.close()
    (t,) = made
    assert t.total == 4 and t.kw["desc"] == "case" and t.kw["unit"] == "update"
    assert t.kw["smoothing"] == 0      # the mean rate since the compiling update (an EMA follows a slow encounter)
    # the clock restarts after the compiling first update, which counts as the initial one
    assert ("reset", 4) in t.events and t.initial == 1
    assert [e for e in t.events if e[0] == "update"] == [("update", 1)] * 3
    assert t.n == 4 and t.events[-1] == ("close",)
