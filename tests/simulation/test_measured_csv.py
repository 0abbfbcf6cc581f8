"""read_measured_csv: the measured-data CSV contract and its rejections (line/column messages)."""
import re

import numpy as np
import pytest

from planner.simulation.recording import read_measured_csv

JOINTS = ("slew", "boom", "jib", "tele")
# column numbers (1-based) of the good file with pressures
T, U_SLEW, U_BOOM, Q_SLEW, Q_JIB, P_BOOM_A, P_TELE_B = 1, 2, 3, 6, 8, 12, 17


def _good(path, n=60, joints=JOINTS, pressures=True, dt=0.02):
    t = np.arange(n) * dt
    cols = ["t"] + [f"u_{j}" for j in joints] + [f"q_{j}" for j in joints]
    if pressures:
        cols += [f"p_{j}_{s}" for j in joints for s in "ab"]
    rows = [[ti] + [0.1] * len(joints) + [0.2] * len(joints)
            + ([1e6] * 2 * len(joints) if pressures else []) for ti in t]
    path.write_text(",".join(cols) + "\n"
                    + "\n".join(",".join(f"{v:.10g}" for v in r) for r in rows) + "\n")
    return path


def _lines(path):
    return path.read_text().split("\n")


def _set_cell(path, line, column, text):
    """Replace the cell at (line, column), both 1-based, header = line 1."""
    lines = _lines(path)
    cells = lines[line - 1].split(",")
    cells[column - 1] = text
    lines[line - 1] = ",".join(cells)
    path.write_text("\n".join(lines))
    return path


def _set_header(path, header):
    lines = _lines(path)
    lines[0] = header
    path.write_text("\n".join(lines))
    return path


def _drop_columns(path, names):
    lines = [ln.split(",") for ln in _lines(path)]
    keep = [i for i, c in enumerate(lines[0]) if c not in names]
    path.write_text("\n".join(",".join(r[i] for i in keep) if r != [""] else "" for r in lines))
    return path


def _rejects(path, *parts, joints=JOINTS):
    """read_measured_csv raises ValueError starting with the path and containing every part."""
    with pytest.raises(ValueError, match=re.escape(parts[0])) as err:
        read_measured_csv(path, joints)
    msg = str(err.value)
    assert msg.startswith(str(path)), msg
    for p in parts[1:]:
        assert p in msg, (p, msg)
    return msg


# ----------------------------------------------------------------------------- good files
def test_good_file_round_trips(tmp_path):
    p = _good(tmp_path / "good.csv")
    r = read_measured_csv(p, JOINTS)
    assert r["columns"] == _lines(p)[0].split(",")
    np.testing.assert_allclose(r["t"], np.arange(60) * 0.02, rtol=0, atol=1e-12)
    for key, value in (("u", 0.1), ("q", 0.2), ("p_a", 1e6), ("p_b", 1e6)):
        assert r[key].shape == (60, 4) and r[key].dtype == float
        np.testing.assert_array_equal(r[key], value)


def test_positions_only_and_no_commands(tmp_path):
    p = _good(tmp_path / "pos.csv", pressures=False)
    r = read_measured_csv(p, JOINTS)
    assert r["p_a"] is None and r["p_b"] is None and r["u"].shape == (60, 4)
    _drop_columns(p, {f"u_{j}" for j in JOINTS})
    r = read_measured_csv(p, JOINTS)
    assert r["u"] is None and r["q"].shape == (60, 4)


def test_column_order_extra_columns_crlf_bom_and_trailing_blank_lines(tmp_path):
    p = tmp_path / "odd.csv"
    header = "t,note,p_boom_b,q_tele,q_jib,u_slew,p_slew_a,q_boom,u_boom,q_slew,u_jib,u_tele," \
             "p_slew_b,p_boom_a,p_jib_a,p_jib_b,p_tele_a,p_tele_b,,spare"
    cols = header.split(",")
    lines = [header]
    for k in range(3):
        val = {c: str(10 * i + k) for i, c in enumerate(cols)}
        val["t"], val["note"], val[""], val["spare"] = str(0.5 * k), "free text", "", "x"
        val["u_slew"] = val["u_boom"] = val["u_jib"] = val["u_tele"] = str(-0.5 + 0.25 * k)
        lines.append(",".join(val[c] for c in cols))
    p.write_bytes(("\ufeff" + "\r\n".join(lines) + "\r\n\r\n  \r\n\n").encode("utf-8"))
    r = read_measured_csv(p, JOINTS)
    assert r["columns"] == cols
    np.testing.assert_array_equal(r["t"], [0, 0.5, 1.0])
    i = {c: n for n, c in enumerate(cols)}
    np.testing.assert_array_equal(r["q"][:, 3], [10 * i["q_tele"] + k for k in range(3)])
    np.testing.assert_array_equal(r["p_b"][:, 1], [10 * i["p_boom_b"] + k for k in range(3)])
    np.testing.assert_array_equal(r["p_a"][:, 0], [10 * i["p_slew_a"] + k for k in range(3)])
    np.testing.assert_array_equal(r["u"][:, 0], [-0.5, -0.25, 0.0])


def test_small_rounding_is_accepted(tmp_path):
    p = _good(tmp_path / "ok.csv")
    _set_cell(p, 10, T, f"{8 * 0.02 * (1 + 1e-9):.17g}")           # jitter far below 1e-6
    _set_cell(p, 11, U_BOOM, "1.0000000001")                       # |u| - 1 < 1e-9
    _set_cell(p, 12, P_BOOM_A, "-9e5")                             # noisy near-zero pressure
    r = read_measured_csv(p, JOINTS)
    assert r["u"][9, 1] > 1.0 and r["p_a"][10, 1] == -9e5


def test_long_recording_written_with_10_digits_is_uniform(tmp_path):
    # 300 s at 30 Hz: the 10 significant digits round t by up to 5e-8 s, i.e. > 1e-6 of a step
    p = _good(tmp_path / "long.csv", n=9000, dt=1 / 30)
    assert read_measured_csv(p, JOINTS)["t"].shape == (9000,)


def test_a_60_s_recording_with_extra_columns(tmp_path):
    p = _good(tmp_path / "big.csv", n=3000)                       # 3000 rows x 17 columns
    lines = _lines(p)
    lines = [lines[0] + ",x1,x2,x3,x4"] + [ln + ",1.5,2.5,3.5,4.5" for ln in lines[1:] if ln]
    p.write_text("\n".join(lines) + "\n")                     # 21 columns: extras ignored
    r = read_measured_csv(p, JOINTS)
    assert r["q"].shape == (3000, 4) and len(r["columns"]) == 21


# ----------------------------------------------------------------------------- file level
def test_missing_file_and_directory_raise_oserror(tmp_path):
    with pytest.raises(OSError):
        read_measured_csv(tmp_path / "nope.csv", JOINTS)
    with pytest.raises(OSError):
        read_measured_csv(tmp_path, JOINTS)


@pytest.mark.parametrize("content", ["", "\n\n", "   \r\n"])
def test_empty_file(tmp_path, content):
    p = tmp_path / "empty.csv"
    p.write_text(content)
    _rejects(p, "line 1: empty file", "header row")


def test_blank_first_line(tmp_path):
    p = _good(tmp_path / "b.csv")
    p.write_text("\n" + p.read_text())
    _rejects(p, "line 1: blank line where the header row is expected")


def test_header_only(tmp_path):
    p = tmp_path / "h.csv"
    p.write_text("t,q_slew,q_boom,q_jib,q_tele\n\n")
    _rejects(p, "line 1: header only, no data rows", "at least 2 data rows")


def test_single_data_row(tmp_path):
    p = tmp_path / "one.csv"
    p.write_text("t,q_slew,q_boom,q_jib,q_tele\n0,0,0,0,0\n")
    _rejects(p, "line 2: only 1 data row", "at least 2 data rows")


def test_not_utf8(tmp_path):
    p = _good(tmp_path / "latin.csv")
    p.write_bytes(p.read_bytes().replace(b"\n0.04,", b"\n0.04\xb0,", 1))
    _rejects(p, "line 4: byte b'\\xb0' is not UTF-8", "UTF-8")


# ----------------------------------------------------------------------------- header
def test_first_column_not_t(tmp_path):
    p = _good(tmp_path / "h.csv")
    _set_header(p, "time" + _lines(p)[0][1:])
    _rejects(p, "line 1, column 1: first column must be 't'", "'time'")


def test_semicolon_separated_gets_a_hint(tmp_path):
    p = _good(tmp_path / "semi.csv")
    p.write_text(p.read_text().replace(",", ";"))
    _rejects(p, "line 1, column 1: first column must be 't'", "comma-separated")


def test_duplicate_column(tmp_path):
    p = _good(tmp_path / "dup.csv")
    _set_cell(p, 1, Q_JIB, "q_slew")
    _rejects(p, f"line 1, column {Q_JIB}: duplicate column name 'q_slew'", f"column {Q_SLEW}")


@pytest.mark.parametrize("column,name", [(U_BOOM, "u_arm"), (Q_SLEW, "q_arm"),
                                         (P_BOOM_A, "p_arm_a"), (P_TELE_B, "p_arm_b")])
def test_unknown_joint(tmp_path, column, name):
    p = _set_cell(_good(tmp_path / "u.csv"), 1, column, name)
    _rejects(p, f"line 1, column {column}: unknown joint 'arm' in column name '{name}'",
             "joints: slew, boom, jib, tele")


def test_missing_position_column(tmp_path):
    p = _drop_columns(_good(tmp_path / "q.csv"), {"q_jib", "q_tele"})
    _rejects(p, "line 1: missing column(s) q_jib, q_tele")


def test_commands_for_some_joints_only(tmp_path):
    p = _drop_columns(_good(tmp_path / "u.csv"), {"u_jib"})
    _rejects(p, "line 1: command column(s) u_jib missing", "every joint or for none")


def test_one_side_of_a_cylinder_only(tmp_path):
    p = _drop_columns(_good(tmp_path / "p.csv"), {"p_boom_b"})
    _rejects(p, f"line 1, column {P_BOOM_A} (p_boom_a): p_boom_b missing", "both")


def test_pressures_for_some_joints_only(tmp_path):
    p = _drop_columns(_good(tmp_path / "p.csv"), {"p_jib_a", "p_jib_b", "p_tele_a", "p_tele_b"})
    _rejects(p, "line 1: pressure columns missing for joint(s) jib, tele",
             "p_jib_a, p_jib_b, p_tele_a, p_tele_b", "positions only")


# ----------------------------------------------------------------------------- rows and cells
def test_row_with_too_few_fields(tmp_path):
    p = _good(tmp_path / "f.csv")
    lines = _lines(p)
    lines[6] = lines[6].rsplit(",", 1)[0]
    p.write_text("\n".join(lines))
    _rejects(p, "line 7: 16 field(s), expected 17")


def test_row_with_too_many_fields(tmp_path):
    p = _good(tmp_path / "f.csv")
    lines = _lines(p)
    lines[3] += ","
    p.write_text("\n".join(lines))
    _rejects(p, "line 4: 18 field(s), expected 17")


def test_blank_line_inside_the_data(tmp_path):
    p = _good(tmp_path / "b.csv")
    lines = _lines(p)
    p.write_text("\n".join(lines[:5] + [""] + lines[5:]))
    _rejects(p, "line 6: blank line inside the data", "expected 17 fields")


@pytest.mark.parametrize("line,column,name,text,found", [
    (5, U_BOOM, "u_boom", "abc", "'abc' is not a number"),
    (9, Q_JIB, "q_jib", "", "empty cell"),
    (9, Q_JIB, "q_jib", "  ", "empty cell"),
    (3, T, "t", "0.02s", "'0.02s' is not a number"),
    (30, P_TELE_B, "p_tele_b", "1;5e6", "'1;5e6' is not a number"),
])
def test_cell_not_a_number(tmp_path, line, column, name, text, found):
    p = _set_cell(_good(tmp_path / "n.csv"), line, column, text)
    _rejects(p, f"line {line}, column {column} ({name}): {found}", "expected a decimal number")


@pytest.mark.parametrize("text", ["nan", "NaN", "inf", "-inf", "Infinity"])
def test_non_finite_value(tmp_path, text):
    p = _set_cell(_good(tmp_path / "nan.csv"), 7, Q_SLEW, text)
    _rejects(p, f"line 7, column {Q_SLEW} (q_slew): {text!r} is not a finite number",
             "NaN and inf are not allowed")


def test_extra_columns_are_not_parsed(tmp_path):
    p = _good(tmp_path / "x.csv")
    lines = _lines(p)
    p.write_text("\n".join(ln + (",comment" if i == 0 else ",nan" if i % 2 else ",n/a")
                           for i, ln in enumerate(lines) if ln) + "\n")
    assert read_measured_csv(p, JOINTS)["q"].shape == (60, 4)


# ----------------------------------------------------------------------------- time
@pytest.mark.parametrize("text,found", [("0.06", "0.06 is not after 0.06"),
                                        ("0.01", "0.01 is not after 0.06")])
def test_time_not_strictly_increasing(tmp_path, text, found):
    p = _set_cell(_good(tmp_path / "t.csv"), 6, T, text)        # line 5 holds t = 0.06
    _rejects(p, "line 6, column 1 (t): time " + found, "(line 5)", "increase strictly")


def test_time_step_not_uniform(tmp_path):
    # issue 14: timestamp jitter (within 10 % of the step) is resampled, a larger step refused
    p = _set_cell(_good(tmp_path / "t.csv"), 21, T, "0.386")     # 0.38 + 0.006: a 30 % step
    _rejects(p, "line 21, column 1 (t): time step 0.026 s", "median step 0.02 s",
             "fixed sample rate")


def test_timestamp_jitter_is_resampled_onto_the_mean_rate(tmp_path):
    p = _set_cell(_good(tmp_path / "t.csv"), 21, T, "0.3801")    # 0.38 + 1e-4: jitter
    r = read_measured_csv(p, JOINTS)
    np.testing.assert_allclose(r["t"], np.arange(60) * 0.02, rtol=0, atol=1e-12)
    assert len(r["notes"]) == 1 and "jitter" in r["notes"][0] and "50 Hz" in r["notes"][0]


def test_jitter_of_almost_ten_percent_on_every_stamp_is_accepted(tmp_path):
    """Issue 14: stamps jittered by up to ±10 % of the step (here ±9.9 %, every one of them,
    two neighbours at opposite extremes) are resampled, not refused: the step test is against
    the mean step, which jitter leaves as it is (against the median, 2 of 8 such logs failed)."""
    p = _good(tmp_path / "t.csv", n=200)
    lines = _lines(p)
    rng = np.random.default_rng(3)
    e = rng.uniform(-0.099, 0.099, 200)
    e[100], e[101] = 0.099, -0.099                  # a step of 0.802 × the nominal one
    e[150], e[151] = -0.099, 0.099                  # … and one of 1.198 ×
    for i in range(1, 199):                         # first and last stamps as logged
        cells = lines[i + 1].split(",")
        cells[0] = f"{(i + e[i]) * 0.02:.10g}"
        lines[i + 1] = ",".join(cells)
    p.write_text("\n".join(lines))
    r = read_measured_csv(p, JOINTS)
    np.testing.assert_allclose(r["t"], np.arange(200) * 0.02, rtol=0, atol=1e-12)
    assert any("jitter" in n for n in r["notes"])


def test_dropped_sample_is_a_non_uniform_step(tmp_path):
    p = _good(tmp_path / "t.csv")
    lines = _lines(p)
    p.write_text("\n".join(lines[:11] + lines[12:]))             # drop t = 0.2 (line 12)
    _rejects(p, "line 12, column 1 (t): time step 0.04 s (from 0.18 to 0.22)",
             "median step 0.02 s")


# ----------------------------------------------------------------------------- ranges
@pytest.mark.parametrize("text", ["1.5", "-1.01", "100"])
def test_command_out_of_range(tmp_path, text):
    p = _set_cell(_good(tmp_path / "u.csv"), 8, U_BOOM, text)
    _rejects(p, f"line 8, column {U_BOOM} (u_boom): command {float(text)!r} outside [-1, 1]")


def test_first_offending_command_is_reported_in_file_order(tmp_path):
    p = _set_cell(_good(tmp_path / "u.csv"), 9, U_SLEW, "2")
    _set_cell(p, 8, U_BOOM + 2, "-2")                           # u_tele, earlier line
    _set_cell(p, 8, U_BOOM, "3")                                # same line, earlier column
    _rejects(p, f"line 8, column {U_BOOM} (u_boom): command 3.0")


def test_pressure_too_low(tmp_path):
    # issue 14: gauge pressures down to -2 MPa are read
    p = _set_cell(_good(tmp_path / "p.csv"), 40, P_BOOM_A, "-2.5e6")
    _rejects(p, f"line 40, column {P_BOOM_A} (p_boom_a): pressure -2500000.0 Pa",
             "not an absolute pressure in Pa (MPa or bar given?)", "allowed: -2e6 ... 1e9 Pa")
    p = _set_cell(_good(tmp_path / "p.csv"), 40, P_BOOM_A, "-2e6")
    assert read_measured_csv(p, JOINTS)["p_a"][38, 1] == -2e6


def test_pressure_too_high(tmp_path):
    p = _set_cell(_good(tmp_path / "p.csv"), 41, P_TELE_B, "2.5e10")
    _rejects(p, f"line 41, column {P_TELE_B} (p_tele_b): pressure 25000000000.0 Pa",
             "above 1e9 Pa", "wrong unit", "allowed: -2e6 ... 1e9 Pa")
