"""The compiled hover solve against the numpy implementation it replaced (the oracle,
``rotoruq.rotor._reference``), and its independence of batch, slicing and thread count.

Tolerances: loads, coefficients, coning, pitch and inflow agree to 1e-10 relative (of at least
1e-4 x the batch's median magnitude: a thrust that cancels to ~0 N has no relative accuracy
either); hub moments of at least half the thrust [N m]; the motion
harmonics to 1e-10 of the largest harmonic of the same degree of freedom (a harmonic that is
zero up to round-off has no relative accuracy); the iteration's last step and the equation
residual, both differences at round-off level (about 1e-9 rad), to 1e-13 absolute. The two
implementations take the same number of iterations and give the same failure reasons, except
for samples that fail after more than 50 wandering iterations (see ``_compare``).
"""

import subprocess
import sys
from dataclasses import fields

import numba
import numpy as np
import pytest
from numba.core import types
from numba.core.extending import intrinsic

from rotoruq.errors import ParameterError
from rotoruq.rotor import _kernel as kern
from rotoruq.rotor._reference import solve_hover_reference
from rotoruq.rotor.aero import LinearAirfoil
from rotoruq.rotor.hover import (
    PARALLEL_MIN_BATCH,
    HoverSolution,
    airfoil_samples,
    airfoil_table,
    rotor_constants,
    sample_inputs,
)
from rotoruq.rotor.model import RotorModel
from rotoruq.rotor.presets import bo105, gvpm

RTOL = 1e-10
CHAOTIC_ITERATIONS = 50
FLOOR = 1e-4
ATOL_RESIDUAL = 1e-13
RELATIVE = ("thrust", "torque", "power", "ct", "cq", "coning_deg", "theta_75_deg",
            "inflow_ratio", "stalled_fraction")
HARMONICS = ("flap", "lag", "feather")

GVPM_IN = ["collective_deg", "lateral_deg", "longitudinal_deg", "k_pitch_link", "c_pitch_link",
           "ei_flap", "height_over_radius", "omega", "cm0", "aero_center_offset",
           "cla_m02", "cl0_m03", "cda2_m02", "cda_m03", "cd0_m04"]
GVPM_MEAN = [5.4, 0.0, 0.0, 15.0, 0.05, 8.5, 2.0, 224.5, 0.0, -0.001,
             0.1055, 0.0, 1.2e-5, 0.0, 0.0077]
GVPM_STD = [1.5, 1.5, 1.5, 6.0, 0.02, 2.0, 1.0, 15.0, 0.004, 0.001,
            0.006, 0.01, 2e-6, 1e-4, 0.0006]
BO_IN = ["collective_deg", "lateral_deg", "longitudinal_deg", "k_flap", "k_lag",
         "k_pitch_link", "height_over_radius", "cla_m03", "cla_m05", "cl0_m06"]
BO_MEAN = [6.0, 0.0, -2.0, 15035.0, 70698.0, 1e9, 2.5, 0.1075, 0.1172, 0.0]
BO_STD = [2.0, 1.5, 1.5, 3000.0, 10000.0, 0.0, 1.0, 0.006, 0.006, 0.02]


def _draw(mean, std, n, seed, inf_share=0.2):
    rng = np.random.default_rng(seed)
    x = np.asarray(mean) + np.asarray(std) * rng.standard_normal((n, len(mean)))
    return x, rng


def _oracle(model, x):
    """The numpy solve of the same points with the model's settings."""
    n = len(x)
    cols = {name: x[:, j] for j, name in enumerate(model.names_in)}
    params = {k: cols.get(k, np.full(n, v)) for k, v in model.defaults().items()}
    if "k_feather" in cols:
        params["k_feather"] = cols["k_feather"]
    over = {k: cols[k] for k in model._airfoil_names if k in cols}
    return solve_hover_reference(model.preset, model.airfoil, model.grid, params, over,
                                 n_harmonics=model.n_harmonics, tolerance=model.tolerance,
                                 max_iterations=model.max_iterations,
                                 check_tolerance=model.check_tolerance)


def _compare(sol: HoverSolution, ref: HoverSolution):
    np.testing.assert_array_equal(sol.converged, ref.converged)
    # A sample the oracle fails after many iterations wanders (torsional divergence, deep
    # stall: the fixed point is repelling) and amplifies round-off: it fails here as well,
    # possibly after another number of iterations or for the neighbouring reason.
    steady = ref.converged | (ref.iterations <= CHAOTIC_ITERATIONS)
    np.testing.assert_array_equal(sol.iterations[steady], ref.iterations[steady])
    assert list(sol.failure[steady]) == list(ref.failure[steady])
    assert (~steady).sum() <= 0.05 * steady.size
    ok = ref.converged
    for name in RELATIVE:
        a, b = getattr(sol, name)[ok], getattr(ref, name)[ok]
        # floor: a value that cancels to ~0 (thrust near zero collective) keeps the absolute
        # accuracy of the typical value, 1e-4 x the median magnitude
        floor = FLOOR * np.median(np.abs(b))
        assert np.all(np.abs(a - b) <= RTOL * np.maximum(np.abs(b), floor)), name
    # hub moments: relative to the sample's thrust x radius where the moment itself is ~0
    scale = np.abs(ref.thrust[ok]) * 0.5
    for name in ("roll", "pitch"):
        a, b = getattr(sol, name)[ok], getattr(ref, name)[ok]
        assert np.all(np.abs(a - b) <= RTOL * np.maximum(np.abs(b), scale)), name
    for name in HARMONICS:
        a, b = getattr(sol, name)[ok], getattr(ref, name)[ok]
        size = np.max(np.abs(b), axis=1, keepdims=True)
        assert np.all(np.abs(a - b) <= RTOL * size), name
    for name in ("residual", "equation_residual"):
        a, b = getattr(sol, name)[ok], getattr(ref, name)[ok]
        np.testing.assert_allclose(a, b, rtol=0, atol=ATOL_RESIDUAL, err_msg=name)


def _check(model, x):
    """Compare on the rows the model solves (it rejects invalid inputs before solving)."""
    model.evaluate(x)
    solved = model.last_solution.iterations > 0
    model.evaluate(x[solved])
    sol = model.last_solution
    _compare(sol, _oracle(model, x[solved]))
    return sol


def test_gvpm_equals_numpy_oracle_on_random_points():
    """Cyclic, ground effect (down to z/R = 0.7 and out of it), airfoil fit overrides in CL
    and CD, a flexible pitch link and the aerodynamic-centre offset; failing rows included."""
    x, rng = _draw(GVPM_MEAN, GVPM_STD, 2000, 1)
    h = GVPM_IN.index("height_over_radius")
    x[:, h] = np.where(rng.random(2000) < 0.2, np.inf, np.clip(x[:, h], 0.7, None))
    k = GVPM_IN.index("k_pitch_link")
    x[:, k] = np.abs(x[:, k]) + 1.0
    sol = _check(RotorModel("gvpm", names_in=GVPM_IN, names_out=["thrust"]), x)
    assert sol.converged.sum() > 1500
    assert (~sol.converged).sum() > 5, "the comparison covers failure reasons as well"


def test_bo105_equals_numpy_oracle_on_random_points():
    x, rng = _draw(BO_MEAN, BO_STD, 1000, 2)
    h = BO_IN.index("height_over_radius")
    x[:, h] = np.where(rng.random(1000) < 0.3, np.inf, np.clip(x[:, h], 0.7, None))
    sol = _check(RotorModel("bo105", names_in=BO_IN, names_out=["thrust"]), x)
    assert sol.converged.sum() > 800


@pytest.mark.parametrize("preset", [
    gvpm(inflow="bemt", harmonic_inflow=True),            # BEMT stations, tip loss
    gvpm(harmonic_inflow=True, tip_loss=False),            # first-harmonic inflow
    bo105(pitching_moment=False, delta3_deg=20.0, k_pitch_link=2e5),
])
def test_other_solver_paths_equal_numpy_oracle(preset):
    names = ["collective_deg", "lateral_deg", "longitudinal_deg", "height_over_radius"]
    x, rng = _draw([6.0, 0.0, 0.0, 2.0], [2.0, 1.5, 1.5, 0.8], 150, 3)
    x[:, 3] = np.clip(x[:, 3], 0.7, None)
    sol = _check(RotorModel(preset, names_in=names, names_out=["thrust"]), x)
    assert sol.converged.sum() > 100


def test_linear_airfoil_equals_numpy_oracle():
    names = ["collective_deg", "lateral_deg", "cla", "cl0", "cd0"]
    x, _ = _draw([6.0, 0.0, 0.1, 0.0, 0.01], [2.0, 1.0, 0.01, 0.05, 0.002], 200, 4)
    model = RotorModel(gvpm(k_pitch_link=1e9), airfoil=LinearAirfoil(cda2=1e-4),
                       names_in=names, names_out=["thrust"])
    _check(model, x)


def _all_equal(a: HoverSolution, b: HoverSolution):
    for f in fields(HoverSolution):
        u, v = getattr(a, f.name), getattr(b, f.name)
        if u.dtype.kind in "fc":
            assert np.array_equal(u, v, equal_nan=True), f.name
        else:
            assert np.array_equal(u, v), f.name


def test_bitwise_independent_of_batch_slices_and_threads():
    x, rng = _draw(GVPM_MEAN, GVPM_STD, 300, 5)
    x[:, GVPM_IN.index("k_pitch_link")] = np.abs(x[:, GVPM_IN.index("k_pitch_link")]) + 1.0
    x[7, 0] = 60.0                                            # a failing row among them
    model = RotorModel("gvpm", names_in=GVPM_IN, names_out=["thrust"])
    threads = numba.get_num_threads()
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba has a single thread on this machine")
    try:
        numba.set_num_threads(1)
        model.evaluate(x)
        one = model.last_solution
        numba.set_num_threads(2)
        model.evaluate(x)
        two = model.last_solution
    finally:
        numba.set_num_threads(threads)
    _all_equal(one, two)
    # alone, in sub-batches of other sizes (below and above the threaded size) and shuffled
    assert PARALLEL_MIN_BATCH < 40
    solved = np.flatnonzero(one.iterations > 0)
    picks = tuple(solved[[0, 1, 2, len(solved) // 2, -1]])
    alone = []
    for i in picks:
        model.evaluate(x[i:i + 1])
        alone.append(model.last_solution)
    for i, s in zip(picks, alone, strict=True):
        for f in fields(HoverSolution):
            u, v = getattr(s, f.name)[0], getattr(one, f.name)[i]
            assert np.array_equal(u, v, equal_nan=True) if np.asarray(u).dtype.kind in "fc" \
                else np.array_equal(u, v), f.name
    parts = []
    for start, stop in ((0, 3), (3, 43), (43, 300)):
        model.evaluate(x[start:stop])
        parts.append(model.last_solution)
    _all_equal(HoverSolution.concatenate(parts), one)
    perm = rng.permutation(len(x))
    model.evaluate(x[perm])
    shuffled = model.last_solution
    for f in fields(HoverSolution):
        u = getattr(shuffled, f.name)
        back = np.empty_like(u)
        back[perm] = u
        v = getattr(one, f.name)
        assert np.array_equal(back, v, equal_nan=True) if u.dtype.kind in "fc" \
            else np.array_equal(back, v), f.name


def test_an_airfoil_the_kernel_cannot_take_is_refused():
    class Custom:
        def coefficients(self, alpha, mach, overrides=None):
            return alpha, alpha, alpha

    with pytest.raises(ParameterError, match="Airfoil .*LinearAirfoil"):
        RotorModel("gvpm", airfoil=Custom())


def test_cli_evaluate_equals_numpy_oracle():
    """The user's path: ``rotoruq evaluate`` runs the compiled solve."""
    out = subprocess.run(
        [sys.executable, "-m", "rotoruq.study.cli", "evaluate", "--preset", "gvpm", "--set",
         "collective_deg=4,5.4,7", "--responses", "thrust", "torque", "--json"],
        capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    import json

    rows = json.loads(out.stdout)
    model = RotorModel("gvpm", names_in=["collective_deg"], names_out=["thrust", "torque"])
    ref = _oracle(model, np.array([[4.0], [5.4], [7.0]]))
    got = np.array([[r["thrust"], r["torque"]] for r in rows])
    np.testing.assert_allclose(got[:, 0], ref.thrust, rtol=RTOL)
    np.testing.assert_allclose(got[:, 1], ref.torque, rtol=RTOL)


def test_mach_interval_search_from_any_start_equals_a_scan_from_zero():
    """The kernel searches a station's Mach interval from the neighbouring azimuth's; from
    every start it must give the interval and weight of np.searchsorted (clamped to the
    grid's end intervals; NaN: interval 0, as the scan from 0 gives)."""
    from rotoruq.rotor import _kernel as kern
    from rotoruq.rotor.hover import airfoil_table

    table = airfoil_table(RotorModel("gvpm").airfoil)
    grid, inv_dx = table.mach, table.mach_inv_dx
    xs = np.concatenate([grid, grid[:-1] + 0.3 * np.diff(grid), [-0.5, -1e-300, 0.95, 7.0]])
    im = np.empty((2, 1), dtype=np.int64)
    s = np.empty((2, 1))
    for x in xs:
        want = min(max(int(np.searchsorted(grid, x, side="right")) - 1, 0), grid.size - 2)
        weight = min(max((abs(x) - grid[want]) * inv_dx[want], 0.0), 1.0) if x >= 0 else None
        for start in range(grid.size - 1):
            # the first azimuth puts the search at interval `start`, the second searches x
            mach = np.array([[grid[start]], [x]])
            kern._mach_intervals(mach, grid, inv_dx, im, s)
            assert im[0, 0] == start
            if x >= 0:
                assert (im[1, 0], s[1, 0]) == (want, weight), (x, start)
            else:   # |Mach| is searched: a negative number is its magnitude's interval
                assert im[1, 0] == min(max(int(np.searchsorted(grid, -x, side="right")) - 1,
                                           0), grid.size - 2)
    for start in range(grid.size - 1):
        kern._mach_intervals(np.array([[grid[start]], [np.nan]]), grid, inv_dx, im, s)
        assert im[1, 0] == 0


@pytest.mark.parametrize(("column", "value", "reason"), [
    ("collective_deg", np.nan, "collective_deg is nan"),
    ("cla_m02", np.inf, "cla_m02 is inf"),
    ("k_pitch_link", -1.0, "k_pitch_link must be >= 0"),
    ("omega", 0.0, "omega must be > 0"),
    ("omega", 2000.0, "supersonic"),
    ("height_over_radius", np.nan, "height_over_radius is NaN"),
    ("height_over_radius", 0.2, "height_over_radius 0.2"),
    ("lateral_deg", 89.0, "exceeds 90 deg"),
])
def test_a_single_invalid_row_is_refused_before_the_solve(column, value, reason):
    """A batch of one takes the validation's whole-array shortcut: it must still refuse
    every invalid row with the reason the row-by-row checks give."""
    model = RotorModel("gvpm", names_in=GVPM_IN, names_out=["thrust"])
    x = np.array([GVPM_MEAN])
    x[0, GVPM_IN.index("height_over_radius")] = np.inf
    x[0, GVPM_IN.index(column)] = value
    batch = model.evaluate(x)
    assert reason in batch.failures[0]
    assert model.last_solution is None or model.last_solution.iterations[0] == 0


# ---------------------------------------------------------------------------------------------
# the Jacobian's lift slope (issue 28)


def _lift_slope(model, x):
    """The kernel's Jacobian lift slope [1/rad] of each row of x (model inputs)."""
    n = len(x)
    cols = {name: x[:, j] for j, name in enumerate(model.names_in)}
    params = {k: cols.get(k, np.full(n, v)) for k, v in model.defaults().items()}
    over = {k: cols[k] for k in model._airfoil_names if k in cols}
    rot = rotor_constants(model.preset, model.grid, model.n_harmonics)
    table = airfoil_table(model.airfoil)
    fits, linear = airfoil_samples(model.airfoil, over, n)
    prm = sample_inputs(model.preset, model.grid, params, n)
    return _lift_slopes(prm, rot, table, fits, linear)


@numba.njit
def _lift_slopes(prm, rot, table, fits, linear):
    """kern._lift_slope of every row (from compiled code: the stages have no CPython
    wrapper)."""
    ws = kern._workspace(rot)
    out = np.empty(prm.shape[0])
    for s in range(prm.shape[0]):
        out[s] = kern._lift_slope(prm[s], rot, table, fits[s], linear[s], 3.0, ws)
    return out


def test_jacobian_lift_slope_is_the_linear_airfoils_own():
    """CL = cla alpha: the secant is cla in 1/rad exactly (to round-off), within the bounds
    [A0 / 2, 2 A0] of the linear-theory slope A0; outside them it is bounded."""
    cla = np.array([0.08, 0.1, 0.12, 0.005, 0.5])            # [1/deg]
    model = RotorModel(gvpm(), airfoil=LinearAirfoil(cda2=1e-4),
                       names_in=["collective_deg", "cla"], names_out=["thrust"])
    a = _lift_slope(model, np.column_stack([np.full(cla.size, 5.0), cla]))
    expected = np.clip(np.rad2deg(cla), 0.5 * kern.A0, 2.0 * kern.A0)
    np.testing.assert_allclose(a, expected, rtol=1e-12)
    assert a[3] == 0.5 * kern.A0 and a[4] == 2.0 * kern.A0


def test_jacobian_lift_slope_follows_the_table_fits():
    """gvpm's table: within the fit window CL is the fit row's cla alpha + cl0, linear in
    Mach between the rows; the flap-damping-weighted secant lies between the smallest and
    largest cla [1/rad] of the rows the blade's Mach numbers (0.04..0.32) span, and rises
    with them."""
    model = RotorModel("gvpm", names_in=["cla_m00", "cla_m02", "cla_m03", "cla_m04"],
                       names_out=["thrust"])
    x = np.array([[0.100, 0.105, 0.108, 0.110], [0.110, 0.115, 0.118, 0.120]])
    a = _lift_slope(model, x)
    lo, hi = np.rad2deg(x.min(axis=1)), np.rad2deg(x.max(axis=1))
    assert np.all((lo <= a) & (a <= hi))
    assert a[1] > a[0]


@pytest.mark.parametrize("preset,names", [
    ("gvpm", ["collective_deg", "lateral_deg", "longitudinal_deg", "k_pitch_link", "ei_flap",
              "cla_m02", "cla_m03", "cd0_m02", "cd0_m03"]),
    ("bo105", ["collective_deg", "lateral_deg", "longitudinal_deg", "k_flap", "k_lag",
               "cla_m03", "cla_m05"]),
])
def test_cyclic_nominal_point_converges_in_few_iterations(preset, names):
    """At a preset's own nominal point (cyclic, 3 % perturbations) the iteration contracts
    about 20-fold per step: at most 7 iterations to the default 1e-8 (with linear theory's
    lift slope in the Jacobian gvpm took 8-11, bo105 10-12)."""
    model = RotorModel(preset, names_in=names, names_out=["thrust"])
    values = {**model.defaults(), **model.airfoil.nominal_values()}
    nom = np.array([values[name] for name in names])
    rng = np.random.default_rng(28)
    x = nom * (1 + 0.03 * rng.standard_normal((200, nom.size)))
    sol = model.solve(x)
    assert np.all(sol.converged)
    assert sol.iterations.max() <= 7, np.bincount(sol.iterations)


def test_hover_batches_run_the_hover_build_and_forward_rows_at_mu_0_equal_it():
    """A hover batch runs the build compiled without the forward-flight code (``flight`` is
    None: numba prunes those branches, issue 34); a batch with a forward row runs the
    forward build, whose rows at mu = 0 give the hover build's numbers, bit for bit."""
    from rotoruq.rotor.forward import ForwardRotorModel

    names = ["collective_deg", "lateral_deg", "longitudinal_deg"]
    points = np.array([[5.0, -1.0, -1.0], [6.0, 0.5, -0.5], [4.0, 0.0, 0.0]])
    # out of ground effect: a forward row in ground effect is refused before the solve
    fwd = ForwardRotorModel("gvpm", names_in=names + ["advance_ratio"],
                            names_out=["thrust", "torque", "roll_moment", "pitch_moment"])
    hover = RotorModel("gvpm", names_in=names, names_out=["thrust", "torque", "roll", "pitch"],
                       fixed={"height_over_radius": fwd.defaults()["height_over_radius"]})
    a = hover(points)
    assert any(str(sig[-1]) == "none" for sig in kern.solve_samples.signatures)
    mixed = np.column_stack([np.vstack([points, points[:1]]), [0.0, 0.0, 0.0, 0.2]])
    b = fwd(mixed)
    assert np.all(np.isfinite(a)) and np.all(np.isfinite(b))  # the forward row solved
    assert any(str(sig[-1]) == "bool" for sig in kern.solve_samples.signatures)
    np.testing.assert_array_equal(a, b[:3])
    prm = np.zeros((2, kern.N_COLUMNS))
    assert kern.needs_flight(prm) is None
    prm[1, kern.MU] = np.nan
    assert kern.needs_flight(prm) is True
    prm[1, kern.MU] = 0.0
    prm[0, kern.TRIM] = kern.WIND_TUNNEL
    assert kern.needs_flight(prm) is True


@intrinsic
def _meminfo_address(typingctx, ary):
    """The address of an array's memory owner (0: none)."""
    def codegen(context, builder, sig, args):
        meminfo = context.make_array(sig.args[0])(context, builder, value=args[0]).meminfo
        return builder.ptrtoint(meminfo, context.get_value_type(types.intp))
    return types.intp(ary), codegen


@numba.njit
def _borrow_and_write(a, pair):
    b, (c, d) = kern._borrowed(a), kern._borrowed(pair)
    b[1] = 5.0
    c[0, 1] = 6.0
    d[2] = 7
    owners = np.array([_meminfo_address(a), _meminfo_address(b), _meminfo_address(c),
                       _meminfo_address(d), _meminfo_address(b[1:])])
    kern._keep_alive(pair)
    return owners


def test_borrowed_views_share_the_memory_without_a_memory_owner():
    """kern._borrowed (the solve's arrays handed to its stages without reference counting,
    issue 34): an array, or the arrays in a tuple, as views of the same memory, shape and
    strides whose (and whose slices') memory owner is null."""
    a, c, d = np.zeros(3), np.zeros((2, 3))[:, ::2], np.zeros(4, dtype=np.int64)
    owners = _borrow_and_write(a, (c, d))
    assert owners[0] != 0 and np.all(owners[1:] == 0)
    assert a[1] == 5.0 and c[0, 1] == 6.0 and d[2] == 7
    assert np.count_nonzero(a) == 1 and np.count_nonzero(c) == 1 and np.count_nonzero(d) == 1
