"""CL data as CSV (problems/toolpath/cl_csv.py): units, tool axis, feed, wrench, every bad input."""

from __future__ import annotations

import numpy as np
import pytest

from models.errors import InputError
from problems.toolpath.cl_csv import CL_AXIS_NORM_TOL, parse_cl_csv, read_cl_csv

HEADER_5AX = "x_mm,y_mm,z_mm,i,j,k,feed_mm_min,rapid,fx_N,fy_N,fz_N,mx_Nm,my_Nm,mz_Nm"


def test_a_five_axis_file_reads_in_si_with_its_lines():
    text = (
        "# exported by a CAM post\n"
        f"{HEADER_5AX}\n"
        "10,20,30,0,0,1,600,1,0,0,0,0,0,0\n"
        "\n"
        "11.5,20,29,0,0.6,0.8,1200,0,5,-2,40,0,0,1.5\n"
    )
    cl = parse_cl_csv(text, "part.csv")
    assert cl.n == 2
    np.testing.assert_allclose(cl.points_m, [[0.010, 0.020, 0.030], [0.0115, 0.020, 0.029]], rtol=0, atol=1e-15)
    np.testing.assert_allclose(cl.tool_axis, [[0, 0, 1], [0, 0.6, 0.8]], atol=1e-15)
    np.testing.assert_allclose(cl.feed_m_s, [0.01, 0.02], rtol=1e-15)  # 600 mm/min = 10 mm/s
    assert cl.rapid.tolist() == [True, False]
    np.testing.assert_allclose(cl.wrench[1], [5, -2, 40, 0, 0, 1.5])
    assert cl.line.tolist() == [3, 5]  # 1-based lines of the file, comment and blank line counted


def test_metres_three_axis_and_no_optional_columns(tmp_path):
    p = tmp_path / "p.csv"
    p.write_text("X_M, Y_M, Z_M\n0.5,0,0.2\n0.6,0,0.2\n", encoding="utf-8")
    cl = read_cl_csv(p)
    np.testing.assert_array_equal(cl.points_m, [[0.5, 0, 0.2], [0.6, 0, 0.2]])
    assert cl.tool_axis is None and cl.feed_m_s is None and cl.wrench is None
    assert not cl.rapid.any() and cl.source == str(p)


def test_a_rounded_tool_axis_is_normalised_and_a_wrong_one_refused():
    ok = parse_cl_csv("x_mm,y_mm,z_mm,i,j,k\n0,0,0,0,0,1.0004\n")
    assert abs(np.linalg.norm(ok.tool_axis[0]) - 1.0) < 1e-15
    with pytest.raises(InputError, match=r"c.csv: line 3, columns 'i, j, k'.*norm 2"):
        parse_cl_csv("x_mm,y_mm,z_mm,i,j,k\n0,0,0,0,0,1\n0,0,0,0,0,2\n", "c.csv")
    assert CL_AXIS_NORM_TOL <= 1e-3


@pytest.mark.parametrize(
    "text, message",
    [
        ("", r"no header and no data"),
        ("x_mm,y_mm,z_mm\n", r"a header and no data rows"),
        ("x,y,z\n1,2,3\n", r"line 1: column 'x' has no unit; name it x_mm or x_m"),
        ("x_mm,y_mm,z_m\n1,2,3\n", r"one unit for all three"),
        ("x_mm,y_mm,z_mm,speed\n1,2,3,4\n", r"line 1: unknown column 'speed'"),
        ("x_mm,y_mm,z_mm,x_mm\n1,2,3,4\n", r"column 'x_mm' given twice"),
        ("x_mm,y_mm,z_mm,i,j\n1,2,3,0,0\n", r"tool axis i, j, k needs all its columns; missing \['k'\]"),
        ("x_mm,y_mm,z_mm,fx_N\n1,2,3,4\n", r"wrench .* needs all its columns"),
        ("x_mm,y_mm,z_mm,feed_mm_min,feed_m_s\n1,2,3,4,5\n", r"give the feed once"),
        ("x_mm,y_mm,z_mm\n1,2\n", r"line 2: 2 cells, the header has 3"),
        ("x_mm,y_mm,z_mm\n1,2,3\n1,abc,3\n", r"line 3, column 'y_mm': 'abc' is not a number"),
        ("x_mm,y_mm,z_mm\n1,2,nan\n", r"line 2, column 'z_mm': 'nan' is not a number"),
        ("x_mm,y_mm,z_mm,feed_mm_min\n1,2,3,0\n", r"line 2, column 'feed_mm_min': feed 0 must be > 0"),
        ("x_mm,y_mm,z_mm,rapid\n1,2,3,2\n", r"line 2, column 'rapid': 2; expected 0 or 1"),
    ],
)
def test_bad_input_names_the_file_line_and_column(text, message):
    with pytest.raises(InputError, match=message) as exc:
        parse_cl_csv(text, "bad.csv")
    assert str(exc.value).startswith("bad.csv: ")


def test_binary_missing_and_non_utf8_files_are_refused(tmp_path):
    binary = tmp_path / "b.csv"
    binary.write_bytes(b"x_mm,y_mm,z_mm\n\0\1\2")
    with pytest.raises(InputError, match="binary file"):
        read_cl_csv(binary)
    latin = tmp_path / "l.csv"
    latin.write_bytes("x_mm,y_mm,z_mm\n1,2,3 # caf\xe9\n".encode("latin-1"))
    with pytest.raises(
        InputError, match=r"l.csv: line 2: byte 0xe9 at offset 26 is not UTF-8 text; .*save the file as UTF-8"
    ):
        read_cl_csv(latin)
    with pytest.raises(InputError, match="cannot read the CL file"):
        read_cl_csv(tmp_path / "missing.csv")


def test_a_large_file_reads_column_by_column():
    n = 100_000
    x = np.linspace(0.0, 500.0, n)
    text = "x_mm,y_mm,z_mm,feed_mm_min\n" + "\n".join(f"{v:.6f},1,2,1500" for v in x)
    cl = parse_cl_csv(text)
    assert cl.n == n and cl.line[-1] == n + 1
    np.testing.assert_allclose(cl.points_m[:, 0], x * 1e-3, rtol=0, atol=0.5e-9 + 1e-15)  # printed to 1e-6 mm
    np.testing.assert_allclose(cl.feed_m_s, 0.025)
