"""C81 reader, writer and MBDyn-style interpolation."""

from __future__ import annotations

import numpy as np
import pytest

from rotoruq.errors import InputFileError, ParameterError
from rotoruq.rotor.c81 import (
    Bracket,
    C81Block,
    C81Table,
    format_field,
    read_c81,
    wrap_alpha,
    write_c81,
)

MBDYN = "data/airfoils/naca0012.c81"


def bilinear_table(nm=3, title="BILINEAR TEST"):
    """Blocks holding f = 2 + 0.3 a + 1.5 M + 0.01 a M on non-uniform grids (exactly bilinear)."""
    alpha = np.array([-180.0, -90.0, -20.0, -10.0, -2.5, 0.0, 1.0, 7.5, 15.0, 90.0, 180.0])
    mach = np.array([0.0, 0.15, 0.45, 0.8])[:nm] if nm > 1 else np.array([0.3])
    A, M = np.meshgrid(alpha, mach, indexing="ij")

    def f(a, m, k):
        return k * (2.0 + 0.3 * a + 1.5 * m + 0.01 * a * m)

    blocks = [C81Block(mach, alpha, f(A, M, k)) for k in (1.0, 0.5, -0.25)]
    return C81Table(title, *blocks), f


# ---- reading the MBDyn table


def test_reads_mbdyn_table(shared_dir):
    t = read_c81(shared_dir / MBDYN)
    assert t.title == "PROFILO NACA 0012"
    assert t.cl.values.shape == (39, 11) and t.cd.values.shape == (65, 11)
    assert t.cm.values.shape == (47, 9)
    np.testing.assert_array_equal(t.cl.mach, [0, .2, .3, .4, .5, .6, .7, .75, .8, .9, 1.0])
    np.testing.assert_array_equal(t.cm.mach, [.2, .3, .4, .5, .6, .7, .75, .8, .9])
    # the fused fields "-1.161-1.161" of row -11 deg
    row = t.cl.values[t.cl.alpha == -11.0][0]
    np.testing.assert_array_equal(row[:3], [-1.161, -1.161, -1.19])
    assert t.cl.alpha[0] == -180.0 and t.cl.alpha[-1] == 180.0
    assert t.cd.values[t.cd.alpha == 90.0][0, 0] == 2.022
    assert t.cd.values[t.cd.alpha == 0.0][0, 0] == 0.008


def test_mbdyn_table_round_trips_exactly(shared_dir, tmp_path):
    t = read_c81(shared_dir / MBDYN)
    assert read_c81(write_c81(t, tmp_path / "fixed.c81")) == t
    assert read_c81(write_c81(t, tmp_path / "free.c81", free_format=True)) == t


def test_mbdyn_interpolation_by_hand(shared_dir):
    cl = read_c81(shared_dir / MBDYN).cl
    # grid point, mid-Mach (0.25 between .2 and .3), mid-alpha, wrapped alpha, |Mach| and clamp
    assert cl.interpolate(-11.0, 0.1) == pytest.approx(-1.161, abs=1e-15)
    assert cl.interpolate(4.0, 0.25) == pytest.approx(0.5 * (0.422 + 0.44))
    assert cl.interpolate(5.0, 0.25) == pytest.approx(0.5 * (0.5275 + 0.55))
    assert cl.interpolate(4.0 + 720.0, -0.25) == pytest.approx(0.431)
    assert cl.interpolate(4.0, 3.0) == pytest.approx(0.396)  # clamped at M = 1.0


# ---- interpolation against an exactly bilinear function


def test_interpolation_reproduces_bilinear_function():
    t, f = bilinear_table(nm=4)
    rng = np.random.default_rng(1)
    a = rng.uniform(-179.9, 179.9, 5000)
    m = rng.uniform(0.0, 0.8, 5000)
    np.testing.assert_allclose(t.cl.interpolate(a, m), f(a, m, 1.0), rtol=0, atol=1e-11)
    # clamping outside the Mach grid and |Mach|
    np.testing.assert_allclose(t.cl.interpolate(a, 5.0), f(a, 0.8, 1.0), atol=1e-11)
    np.testing.assert_allclose(t.cl.interpolate(a, -0.3), f(a, 0.3, 1.0), atol=1e-11)
    # wrapping: alpha and alpha + 360 k give the same value; 180 wraps to -180
    np.testing.assert_allclose(t.cl.interpolate(a + 360.0, m), t.cl.interpolate(a, m), atol=1e-9)
    np.testing.assert_allclose(t.cl.interpolate(a - 720.0, m), t.cl.interpolate(a, m), atol=1e-9)
    assert t.cl.interpolate(180.0, 0.0) == pytest.approx(f(-180.0, 0.0, 1.0))
    # broadcasting
    assert t.cl.interpolate(np.zeros((3, 1)), np.zeros((1, 5))).shape == (3, 5)


def test_single_mach_block():
    t, f = bilinear_table(nm=1)
    assert t.cl.interpolate(7.5, 0.9) == pytest.approx(f(7.5, 0.3, 1.0))


def test_bracket_matches_searchsorted():
    rng = np.random.default_rng(2)
    grid = np.sort(rng.choice(np.arange(-180.0, 180.5, 0.5), 70, replace=False))
    x = np.concatenate([rng.uniform(-200, 200, 20000), grid, [-1e9, 1e9]])
    i, t = Bracket(grid).locate(x)
    ref = np.clip(np.searchsorted(grid, x, side="right") - 1, 0, grid.size - 2)
    tref = np.clip((x - grid[ref]) / (grid[ref + 1] - grid[ref]), 0, 1)
    # at a grid point both neighbouring intervals give the same interpolant
    same = i == ref
    assert same.mean() > 0.99
    np.testing.assert_allclose(grid[i] + t * (grid[i + 1] - grid[i]),
                               grid[ref] + tref * (grid[ref + 1] - grid[ref]), atol=1e-9)
    i, t = Bracket(grid).locate(np.array([np.nan, 0.0]))
    assert np.isnan(t[0]) and 0 <= i[0] <= grid.size - 2


def test_wrap_alpha():
    np.testing.assert_allclose(wrap_alpha([-540.0, -180.0, 179.0, 180.0, 190.0, 725.0]),
                               [-180.0, -180.0, 179.0, -180.0, -170.0, 5.0])


# ---- writing


def test_round_trip_to_written_precision(tmp_path):
    rng = np.random.default_rng(3)
    mach = np.array([0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.75, 0.8, 0.85, 0.9])  # 12 > 9
    alpha = np.concatenate([[-180.0], np.sort(rng.uniform(-179, 179, 30)), [180.0]])
    vals = [rng.normal(0, 1.0, (alpha.size, mach.size)),
            10.0 ** rng.uniform(-7, 0.5, (alpha.size, mach.size)),
            -rng.uniform(0, 0.2, (alpha.size, mach.size))]
    t = C81Table("RANDOM", *[C81Block(mach, alpha, v) for v in vals])
    back = read_c81(write_c81(t, tmp_path / "r.c81"))
    np.testing.assert_array_equal(back.cl.mach, mach)
    for b0, b1 in zip(t.blocks().values(), back.blocks().values(), strict=True):
        # 7-character fields keep at least 4 decimals below 10 and 3 significant digits
        np.testing.assert_allclose(b1.alpha, b0.alpha, atol=5e-3)
        err = np.abs(b1.values - b0.values)
        assert np.all(err <= np.maximum(5e-5, 5e-3 * np.abs(b0.values)))
    text = (tmp_path / "r.c81").read_text().splitlines()
    assert text[0][30:42] == "123212321232"
    assert all(len(line) <= 70 for line in text[1:])
    # free format round-trips exactly
    assert read_c81(write_c81(t, tmp_path / "f.c81", free_format=True)) == t


def test_format_field():
    assert format_field(0.0125) == ".0125"
    assert format_field(-0.5) == "-.5"
    assert format_field(180.0) == "180."
    assert format_field(-1e-12) == "-1.e-12" or float(format_field(-1e-12)) == -1e-12
    for x in (0.123456789, -0.123456789, 12.3456789, 1.2345e-6, -99999.5, 0.1 + 0.2):
        s = format_field(x)
        assert len(s) <= 7
        assert abs(float(s) - x) <= 5e-3 * abs(x)


def test_fixed_format_count_limit(tmp_path):
    alpha = np.linspace(-180, 180, 120)
    b = C81Block([0.0], alpha, np.zeros((120, 1)))
    with pytest.raises(ParameterError, match="99"):
        write_c81(C81Table("BIG", b, b, b), tmp_path / "big.c81")
    assert read_c81(write_c81(C81Table("BIG", b, b, b), tmp_path / "big.c81", True)).cl.alpha.size \
        == 120


def test_free_format_without_marker(tmp_path):
    p = tmp_path / "ff.c81"
    p.write_text("MY AIRFOIL; 2 2 1 2 1 2\n0 0.5\n-180 0 0\n180 0.5 0.5\n0\n-180 1\n180 1\n"
                 "0.3\n-180 0.1\n 180 0.2\n")
    t = read_c81(p)
    assert t.title == "MY AIRFOIL"
    np.testing.assert_array_equal(t.cl.values, [[0, 0], [0.5, 0.5]])
    np.testing.assert_array_equal(t.cm.mach, [0.3])


# ---- malformed files


def _fixed_file(tmp_path, lines):
    p = tmp_path / "bad.c81"
    p.write_text("\n".join(lines) + "\n")
    return p


GOOD = [
    "SMALL".ljust(30) + " 2 3 1 2 1 2",
    "       0.     .5",
    "-180.  0.     0.",
    "0.     .1     .2",
    "180.   0.     0.",
    "       0.",
    "-180.  .02",
    "180.   .02",
    "       .3",
    "-180.  0.",
    "180.   0.",
]


def test_good_small_file(tmp_path):
    t = read_c81(_fixed_file(tmp_path, GOOD))
    np.testing.assert_array_equal(t.cl.values[1], [0.1, 0.2])


def test_bad_header_counts(tmp_path):
    lines = ["SMALL".ljust(30) + " 2 X 1 2 1 2"] + GOOD[1:]
    with pytest.raises(InputFileError) as e:
        read_c81(_fixed_file(tmp_path, lines))
    assert e.value.line == 1 and "ML NL MD ND MM NM" in str(e.value) and "bad.c81" in str(e.value)
    with pytest.raises(InputFileError, match="line 1"):
        read_c81(_fixed_file(tmp_path, ["SHORT HEADER"]))


def test_non_numeric_field(tmp_path):
    lines = list(GOOD)
    lines[3] = "0.     .1     abc"
    with pytest.raises(InputFileError) as e:
        read_c81(_fixed_file(tmp_path, lines))
    assert e.value.line == 4 and "columns 15-21" in str(e.value) and "abc" in str(e.value)


def test_truncated_block(tmp_path):
    with pytest.raises(InputFileError) as e:
        read_c81(_fixed_file(tmp_path, GOOD[:7]))
    assert e.value.line == 8 and "end of file" in str(e.value) and "CD block" in str(e.value)


def test_non_increasing_alpha(tmp_path):
    lines = list(GOOD)
    lines[4] = "-10.   0.     0."
    with pytest.raises(InputFileError) as e:
        read_c81(_fixed_file(tmp_path, lines))
    assert e.value.line == 5 and "strictly increasing" in str(e.value)


def test_wrong_counts_are_caught(tmp_path):
    # header says 2 CL angles but the block has 3: the third row lands where the CD Mach row is
    lines = ["SMALL".ljust(30) + " 2 2 1 2 1 2"] + GOOD[1:]
    with pytest.raises(InputFileError) as e:
        read_c81(_fixed_file(tmp_path, lines))
    assert e.value.line == 5 and "blank columns 1-7" in str(e.value)


def test_missing_file(tmp_path):
    with pytest.raises(InputFileError, match="readable"):
        read_c81(tmp_path / "nope.c81")


def test_block_validation():
    with pytest.raises(ParameterError, match="shape"):
        C81Block([0.0, 0.5], [-180.0, 180.0], np.zeros((2, 3)))
    with pytest.raises(ParameterError, match="increasing"):
        C81Block([0.5, 0.0], [-180.0, 180.0], np.zeros((2, 2)))


@pytest.mark.parametrize(
    "text, line, words",
    [
        ("# FREE FORMAT\n", 2, "free-format header"),
        ("# FREE FORMAT", 2, "free-format header"),
        ("# FREE FORMAT\nT; 1 1 1 1 1 1\n0.3\n0.0 nan\n", 4, "finite number"),
        ("# FREE FORMAT\nT; 1 1 1 1 1 1\n0.3\n0.0 1e999\n", 4, "finite number"),
        ("T".ljust(30) + " 1 1 1 1 1 1\n" + " " * 7 + "nan\n", 2, "finite number"),
    ],
)
def test_malformed_files_name_file_and_line(tmp_path, text, line, words):
    p = tmp_path / "bad.c81"
    p.write_text(text)
    with pytest.raises(InputFileError) as err:
        read_c81(p)
    assert err.value.path == str(p) and err.value.line == line
    assert words in str(err.value)
