"""AIS-style track files (psbmpc_jax.evaltool.ais): the round trip local tracks -> AIS CSV -> evaluate, the
common clock, the projection, and every bad-file error (file, row, column named)."""

from __future__ import annotations

import logging
import math
import pathlib

import numpy as np
import pytest

from psbmpc_jax.apps.cli import main
from psbmpc_jax.evaltool import evaluate_tracks, get_params, load_tracks
from psbmpc_jax.evaltool.ais import KNOT_MPS, ais_frame
from psbmpc_jax.evaltool.synthetic import scripted_tracks
from psbmpc_jax.geo import latlon_to_ned

ROOT = pathlib.Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "ais" / "crossing_trondheimsfjord.csv"
INLAND = get_params("inland_small")
ORIGIN = (63.47, 10.38)
T_80 = 100 - 80 / math.sqrt(2)


def own(knots=(), speed=1.0):
    return dict(start_ne=(0.0, 0.0), course_deg=0.0, speed_mps=speed, course_knots=list(knots))


# scripted encounters (the §6 checks of tests/test_evaltool.py): one of each situation, the own-ship manoeuvring
CASES = {
    "HO": {"O": own([(60, 0), (70, 30)]), "T": dict(start_ne=(200.0, 0.0), course_deg=180.0, speed_mps=1.0)},
    "CRGW": {"O": own([(T_80, 0), (T_80 + 10, 30)]),
             "T": dict(start_ne=(100.0, 100.0), course_deg=270.0, speed_mps=1.0)},
    "CRSO": {"O": own([(70, 0), (80, -30)]), "T": dict(start_ne=(100.0, -100.0), course_deg=90.0, speed_mps=1.0)},
    "OTGW": {"O": own([(20, 0), (25, -30), (45, -30), (50, 0), (115, 0), (125, 90)], speed=1.5),
             "T": dict(start_ne=(100.0, 0.0), course_deg=0.0, speed_mps=0.5)},
}


def irregular_times(rng, t_end=200.0, lo=1.0, hi=3.0, lost=0.1) -> np.ndarray:
    """Report times 1 to 3 s apart, one in ten lost; the first and last sample kept (same span for all)."""
    t = np.cumsum(rng.uniform(lo, hi, int(t_end / lo) + 1))
    t = t[t < t_end - 0.5]
    return np.concatenate([[0.0], t[rng.random(t.size) > lost], [t_end]])


def write(tmp_path, text: str, name: str = "ais.csv") -> pathlib.Path:
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


# --------------------------------------------------------------------------------------------- round trip
@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("sog_cog, unix", [(True, False), (False, True)])
def test_round_trip_gives_the_same_encounters(tmp_path, case, sog_cog, unix):
    """Scripted tracks -> AIS reports at irregular times (lat/lon 1e-6 deg, SOG 0.1 kn, COG 0.1 deg) -> evaluate:
    the same encounters, situations and statuses, and scores close to those of the original NED tracks.

    Tolerances: a lat/lon rounded to 1e-6 deg is off by at most 0.056 m north and 0.025 m east (at 63.5 N), and
    linear interpolation between reports h <= 3 s apart cuts a turn of rate w at speed U by at most U w h^2 / 8
    (0.06 m for the 3 deg/s turns here): 0.2 m on the CPA range covers both with margin (measured: at most 0.051 m
    over 8 seeds of report times, all four cases).  The CPA time lies on the 1 s evaluation grid and may move by
    one sample (measured: 0 or 1 s): 1.5 s.  The scores move with the ranges and with the course/speed resampling;
    0.02 bounds them (measured: at most 0.011 over the 8 seeds, both with SOG/COG and with course and speed derived
    from the positions)."""
    base = scripted_tracks(CASES[case], 200.0, step_s=0.05)
    ref = evaluate_tracks(base, INLAND)
    rng = np.random.default_rng(7)
    times = {n: irregular_times(rng) for n in base.names}
    df = ais_frame(base, *ORIGIN, report_times=times, mmsi={"O": "257000001", "T": "257000002"}, sog_cog=sog_cog)
    if unix:
        import pandas as pd

        df["timestamp"] = ((pd.to_datetime(df["timestamp"], utc=True) - pd.Timestamp("1970-01-01", tz="UTC"))
                           .dt.total_seconds().map(lambda s: f"{s:.3f}"))
    p = tmp_path / "tracks.csv"
    df.to_csv(p, index=False)
    tr = load_tracks(p, own="257000001")
    assert tr.names == ("257000001", "257000002") and tr.own_name == "257000001"
    assert all(type(n) is str for n in tr.names)
    assert tr.t0_utc == ("1714644000.000 (Unix seconds)" if unix else "2024-05-02T10:00:00.000Z")
    ev = evaluate_tracks(tr, INLAND)
    assert [(e.situation, e.status) for e in ev.encounters] == [(e.situation, e.status) for e in ref.encounters]
    assert ref.encounters[0].situation == case
    for a, b in zip(ref.encounters, ev.encounters):
        assert b.r_cpa == pytest.approx(a.r_cpa, abs=0.2)
        assert b.t_cpa == pytest.approx(a.t_cpa, abs=1.5)
        for k in ("S_sit", "S_safety", "S_theta", "S_r", "P_delay"):
            x, y = getattr(a.scores, k), getattr(b.scores, k)
            assert (x is None) == (y is None), k
            if x is not None:
                assert y == pytest.approx(x, abs=0.02), k


def test_common_clock_is_the_overlap_and_the_projection_the_centroid(tmp_path, caplog):
    """Vessel a reports 0..100 s, b 10..90 s: the clock runs from b's first to b's last report, every --dt; the
    reports outside are logged (not silently dropped); positions are metres about the centroid of all reports;
    COG through north is interpolated on the circle."""
    rows = ["timestamp,MMSI,lat,lon,SOG,COG"]
    for k in range(11):                                   # a: north at 1 kn from 63.47 N
        t = 10 * k
        lat = 63.47 + t * KNOT_MPS / 111_000
        rows.append(f"2024-05-02T10:00:{t:02d}Z,a,{lat:.7f},10.38,1.0,{359.0 if k % 2 else 1.0}" if t < 60 else
                    f"2024-05-02T10:01:{t - 60:02d}Z,a,{lat:.7f},10.38,1.0,{359.0 if k % 2 else 1.0}")
    for t in (10, 50, 90):
        rows.append(f"2024-05-02T10:0{t // 60}:{t % 60:02d}Z,b,63.48,10.40,0.0,90.0")
    p = write(tmp_path, "\n".join(rows) + "\n")
    with caplog.at_level(logging.INFO, logger="psbmpc_jax.evaltool.ais"):
        tr = load_tracks(p, own="a", dt=2.0)
    assert tr.t0_utc == "2024-05-02T10:00:10.000Z"
    assert tr.t[0] == 0 and tr.t[-1] == 80 and np.allclose(np.diff(tr.t), 2.0)
    assert "vessel MMSI a: 2 of its 11 reports lie outside the common period" in caplog.text
    lat = np.array([round(63.47 + t * KNOT_MPS / 111_000, 7) for t in range(0, 101, 10)] + [63.48] * 3)
    lon = np.array([10.38] * 11 + [10.40] * 3)
    ne_b = latlon_to_ned(63.48, 10.40, lat.mean(), lon.mean())   # the loader averages lon on the circle: 1e-4 m
    assert tr.north[1] == pytest.approx(np.full(tr.t.size, ne_b[0]), abs=1e-4)
    assert tr.east[1] == pytest.approx(np.full(tr.t.size, ne_b[1]), abs=1e-4)
    assert tr.speed[0] == pytest.approx(KNOT_MPS) and tr.speed[1] == pytest.approx(0.0)
    assert np.all(np.abs(np.degrees(tr.course[0])) <= 1.0 + 1e-9)   # 1 deg <-> 359 deg: never via 180 deg


def test_gap_warning_goes_to_the_logger(tmp_path, caplog, capsys):
    rows = ["timestamp,MMSI,lat,lon"] + [f"{t},1,63.47,{10.38 + t * 1e-5:.6f}" for t in (0, 10, 100, 110)]
    p = write(tmp_path, "\n".join(rows) + "\n")
    with caplog.at_level(logging.WARNING, logger="psbmpc_jax.evaltool.ais"):
        tr = load_tracks(p)
    assert tr.names == ("1",) and tr.t[-1] == 110
    assert "vessel MMSI 1 has no report for 90 s (rows 3 to 4)" in caplog.text
    assert capsys.readouterr().out == ""
    caplog.clear()
    rows = ["timestamp,MMSI,lat,lon"] + [f"{t},1,63.47,{10.38 + t * 1e-5:.6f}" for t in range(0, 700, 100)]
    with caplog.at_level(logging.WARNING, logger="psbmpc_jax.evaltool.ais"):
        load_tracks(write(tmp_path, "\n".join(rows) + "\n", "gaps.csv"))
    assert caplog.text.count("has no report for 100 s") == 3          # the first three, then a count
    assert "vessel MMSI 1 has 3 more gaps longer than 60 s (the longest 100 s)" in caplog.text


# --------------------------------------------------------------------------------------------- bad files
GOOD = "2024-05-02T10:00:00Z,1,63.47,10.38,2.0,10.0\n2024-05-02T10:00:10Z,1,63.4702,10.38,2.0,10.0\n"
HEAD = "timestamp,MMSI,lat,lon,SOG,COG\n"
TWO = HEAD + GOOD + "2024-05-02T10:00:00Z,2,63.48,10.38,2.0,180.0\n2024-05-02T10:00:10Z,2,63.4798,10.38,2.0,180.0\n"


@pytest.mark.parametrize("text, message", [
    (HEAD + GOOD.replace("63.4702", "north"), r"row 3, column lat: not a number: 'north'"),
    (HEAD + GOOD.replace("63.4702", "93.47"), r"row 3, column lat: 93.47 is not a latitude in degrees: -90 to 90"),
    ("timestamp,MMSI,lat,lon\n0,1,10.38,63.47\n10,1,100.38,63.47\n",
     r"row 3, column lat: 100.38 is not a latitude .* are lat and lon swapped\?"),
    (HEAD + GOOD.replace("10.38,2.0,10.0\n2", "190.38,2.0,10.0\n2"),
     r"row 2, column lon: 190.38 is not a longitude in degrees: -180 to 180"),
    (HEAD + GOOD.replace("2.0,10.0\n2", "-0.5,10.0\n2"), r"row 2, column SOG: -0.5 kn is not a speed over ground "
                                                         r"\(negative; 0 to 102.2 kn allowed\)"),
    (HEAD + GOOD.replace("2.0,10.0\n2", "102.3,10.0\n2"), r"row 2, column SOG: 102.3 kn .*'not available'"),
    (HEAD + GOOD.replace("2.0,10.0\n2", "250,10.0\n2"), r"row 2, column SOG: 250 kn .*above the largest speed"),
    (HEAD + GOOD.replace("2.0,10.0\n2", "fast,10.0\n2"), r"row 2, column SOG: not a number: 'fast'"),
    (HEAD + GOOD.replace("2.0,10.0\n2", "2.0,360\n2"), r"row 2, column COG: 360 deg is not a course over ground "
                                                      r"\(0 <= COG < 360 allowed\); 360 is the AIS value"),
    (HEAD + GOOD.replace("2.0,10.0\n2", "2.0,\n2"), r"row 2, column COG: not a number: ''"),
    (HEAD + GOOD.replace("2024-05-02T10:00:10Z", "yesterday"), r"row 3, column timestamp: not a timestamp: "
                                                                 r"'yesterday' \(ISO 8601 .* or Unix seconds"),
    (HEAD + GOOD.replace("2024-05-02T10:00:10Z", "1714644010"),
     r"row 3, column timestamp: not a timestamp: '1714644010' \(the file's other timestamps are ISO 8601"),
    ("timestamp,MMSI,lat,lon\n1714644000000,1,63.47,10.38\n1714644010000,1,63.4702,10.38\n",
     r"row 2, column timestamp: 1714644000000 is not Unix seconds from 1970 to 2100 .* milliseconds or micro"),
    (HEAD + GOOD.replace("Z,1,63.4702", "Z, ,63.4702"), r"row 3, column MMSI: empty vessel identifier"),
    (HEAD + GOOD + "2024-05-02T10:00:10Z,1,63.4703,10.38,2.0,10.0\n",
     r"row 4, column timestamp: vessel MMSI 1 has two reports at '2024-05-02T10:00:10Z' \(rows 3 and 4\)"),
    (TWO + "2024-05-02T10:00:05Z,3,63.49,10.38,2.0,10.0\n",
     r"vessel MMSI 3: at least 2 reports are needed, got 1 \(row 6\)"),
    (HEAD + GOOD + "2024-05-02T11:00:00Z,2,63.48,10.38,2.0,10.0\n2024-05-02T11:00:10Z,2,63.4802,10.38,2.0,10.0\n",
     r"the vessels' time spans do not overlap \(MMSI 1: 2024-05-02T10:00:00Z to 2024-05-02T10:00:10Z; MMSI 2: "),
    (TWO.replace("Z,2,63.48,", "Z,2,65.48,").replace("Z,2,63.4798,", "Z,2,65.4798,"),
     r"row 2, column lat: \(63.47, 10.38\) lies 112.0 km from the centroid of the reports \(64.47500, 10.38000\); "
     r"at most 100 km"),
    (HEAD + GOOD.replace("63.4702", "63.5702"), r"row 3, column lat: vessel MMSI 1 moves 11\d{3} m in 10 s since "
                                                r"row 2 .* a position jump or a wrong timestamp\?"),
    ("timestamp,MMSI,lat,lon,SOG\n0,1,63.47,10.38,2\n10,1,63.4702,10.38,2\n", r"give both optional columns SOG "
                                                                               r"and COG, or neither"),
    ("time,ship,y,x\n0,1,2,3\n", r"the header fits neither accepted format: north/east tracks need t_s,vessel,"
                                 r"north_m,east_m\[,course_deg,speed_mps\] \(missing column\(s\) t_s, vessel, "
                                 r"north_m, east_m\); AIS-style tracks need timestamp,MMSI,lat,lon\[,SOG,COG\] "
                                 r"\(missing column\(s\) timestamp, MMSI, lat, lon\); got time,ship,y,x"),
    ("timestamp,MMSI,lat,latitude,lon\n", r"columns 'lat' and 'latitude' both give lat"),
    (HEAD, r"no data rows"),
])
def test_bad_file_errors_name_file_row_and_column(tmp_path, text, message):
    p = write(tmp_path, text)
    with pytest.raises(ValueError, match=message) as err:
        load_tracks(p, own="1")
    assert str(err.value).startswith(f"{p}: ")


def test_own_ship_required_and_checked(tmp_path):
    p = write(tmp_path, TWO)
    with pytest.raises(ValueError, match=r"2 vessels \(MMSI 1, 2\): choose the own-ship by its MMSI \(--own-mmsi"):
        load_tracks(p)
    with pytest.raises(ValueError, match=r"unknown own-ship '9'; vessels: 1, 2"):
        load_tracks(p, own="9")
    assert load_tracks(p, own=2).own_name == "2"             # an MMSI given as a number
    with pytest.raises(ValueError, match=r"dt \(the common clock's step\) must be a finite number of seconds > 0"):
        load_tracks(p, own="1", dt=0.0)
    with pytest.raises(ValueError, match=r"the vessels are all reported for only 10 s together, shorter than "
                                         r"the clock step dt = 20 s"):
        load_tracks(p, own="1", dt=20.0)


def test_dt_is_refused_for_north_east_files(tmp_path):
    p = write(tmp_path, "t_s,vessel,north_m,east_m\n0,a,0,0\n1,a,1,0\n", "ned.csv")
    with pytest.raises(ValueError, match=r"--dt\) sets the common clock of AIS-style files only"):
        load_tracks(p, dt=1.0)


# ------------------------------------------------------------------------------------------------ CLI
def test_cli_scores_the_example_file(capsys):
    rc = main(["evaluate", str(EXAMPLE), "--own-mmsi", "257000001", "--range-scale", "0.16666667"])
    out = capsys.readouterr().out
    assert rc == 0
    assert "resampled every 1 s over their common period: t = 0 s is 2024-05-02T10:00:" in out
    assert "257000001 vs 257000002: CRGW scored" in out


def test_cli_errors(capsys, tmp_path):
    assert main(["evaluate", str(EXAMPLE)]) == 2
    err = capsys.readouterr().err
    assert f"{EXAMPLE}: 2 vessels (MMSI 257000001, 257000002): choose the own-ship" in err
    bad = write(tmp_path, HEAD + GOOD.replace("63.4702", "x"))
    assert main(["evaluate", str(bad)]) == 2
    assert f"{bad}: row 3, column lat: not a number: 'x'" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["evaluate", str(EXAMPLE), "--dt", "-1"])
    assert "--dt must be a finite number of seconds > 0" in capsys.readouterr().err


def test_evaluate_file_reads_the_example_with_dt():
    from psbmpc_jax.evaltool import evaluate_file
    from psbmpc_jax.evaltool.params import scaled_params

    (ev,) = evaluate_file(EXAMPLE, scaled_params("default", 1 / 6), own="257000001", dt=0.5)
    assert [(e.vessel, e.other, e.situation, e.status) for e in ev.encounters] == [
        ("257000001", "257000002", "CRGW", "scored")]
    assert ev.encounters[0].r_cpa == pytest.approx(59.1, abs=0.1)     # the simulated run's CPA (59.06 m)


def test_track_across_the_antimeridian(tmp_path):
    """10 m/s east along 10 N through lon 180: the centroid's longitude is averaged on the circle, so the track is
    straight and continuous in metres (not 40 000 km long)."""
    m_per_deg = 111_320 * math.cos(math.radians(10))     # ~ metres per degree of longitude at 10 N
    lons = [(179.999 + k * 100 / m_per_deg + 180) % 360 - 180 for k in range(5)]
    assert lons[1] > 0 > lons[2]
    p = write(tmp_path, "timestamp,MMSI,lat,lon\n" + "".join(f"{10 * k},1,10.0,{lon:.7f}\n"
                                                              for k, lon in enumerate(lons)))
    tr = load_tracks(p)
    assert np.all(np.diff(tr.east[0]) > 0) and tr.east[0, -1] - tr.east[0, 0] == pytest.approx(400, abs=1)
    assert tr.speed[0] == pytest.approx(10.0, abs=0.01)
    assert np.degrees(tr.course[0]) == pytest.approx(90.0, abs=0.01)
