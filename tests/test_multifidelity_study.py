"""Multi-fidelity studies: named ``[models.NAME]`` tables, the runner building them by name,
the bundled ``multifidelity_rotor`` study through the CLI (serial and on Dask), the bundled
``mbdyn_multifidelity`` study with the real solver, and every bad ``[models]`` input naming
its line."""

from __future__ import annotations

import sqlite3
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from _inproc import rotoruq
from rotoruq.errors import InputFileError, ParameterError
from rotoruq.results import load_step
from rotoruq.rotor.model import RotorModel
from rotoruq.study.runner import run_study, why_rerun
from rotoruq.study.schema import load_study
from test_mbdyn import env_with_mbdyn, needs_mbdyn
from test_reproducible_studies import (
    THREAD_VARIABLES,
    assert_replays_bitwise,
    counting_mbdyn,
    mbdyn_starts,
)

CLI = [sys.executable, "-m", "rotoruq.study.cli"]
STUDIES = Path(__file__).resolve().parents[1] / "src" / "rotoruq" / "studies"
ROTOR_STUDY = STUDIES / "multifidelity_rotor.toml"


def run_cli(*args: str, cwd: Path, env: dict | None = None, timeout: float = 600,
            fresh: bool = False) -> subprocess.CompletedProcess:
    """``rotoruq ARGS`` from ``cwd``: in the test's process (``tests/_inproc.py``), or with
    ``fresh`` in a new one (a study from a fresh folder, on Dask or MBDyn: the user's path)."""
    if not fresh:
        return rotoruq(*args, cwd=cwd, env=env)
    return subprocess.run([*CLI, *args], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout)


def store_counts(out: Path) -> dict[str, int]:
    """Successful evaluations in the results folder's store, by model identity."""
    with sqlite3.connect(out / "evaluations.sqlite") as con:
        rows = con.execute("SELECT model, COUNT(*) FROM evaluations WHERE status = 'ok' "
                           "GROUP BY model").fetchall()
    return dict(rows)


def quadrature_moments(responses: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Mean and variance of the study's high-fidelity rotor (GVPM, default grid, H/R = 4) over
    collective ~ U(4.5, 6.5) deg and cla_m03 ~ N(0.108, 5.4e-3), by a 20 x 20 tensor Gauss rule
    (Gauss-Legendre x Gauss-Hermite): the responses are smooth in both inputs, so the rule's
    error is far below the estimator's standard errors."""
    xl, wl = np.polynomial.legendre.leggauss(20)
    xh, wh = np.polynomial.hermite_e.hermegauss(20)
    theta = 5.5 + xl
    cla = 0.108 + 5.4e-3 * xh
    w = np.outer(wl / 2.0, wh / np.sqrt(2.0 * np.pi)).ravel()
    x = np.column_stack([np.repeat(theta, xh.size), np.tile(cla, xl.size)])
    y = RotorModel("gvpm", names_in=["collective_deg", "cla_m03"], names_out=responses,
                   fixed={"height_over_radius": 4.0})(x)
    assert np.all(np.isfinite(y))
    mean = w @ y
    return mean, w @ (y - mean) ** 2


def check_estimates(res, responses: list[str], k: float = 4.0) -> None:
    """The step's mean and variance within k of their standard errors of the exact ones."""
    mean, var = quadrature_moments(responses)
    for j, r in enumerate(responses):
        m, se = res.scalars[f"mean/{r}"], res.scalars[f"mean_se/{r}"]
        v, vse = res.scalars[f"variance/{r}"], res.scalars[f"variance_se/{r}"]
        assert se > 0 and vse > 0
        assert abs(m - mean[j]) < k * se, (r, m, mean[j], se)
        assert abs(v - var[j]) < k * vse, (r, v, var[j], vse)


# ------------------------------------------------------------------------------------------
# the analytic study through the CLI


@pytest.mark.slow  # ~21 CPU-s; the step's in-process tests stay fast
def test_rotor_study_through_cli_from_a_fresh_folder(tmp_path):
    """`rotoruq run multifidelity_rotor` in an empty folder: the allocation and estimate tables
    in `rotoruq show` and in the report; mean and variance of thrust and power within 4
    standard errors of the quadrature answer; each model's runs stored under its own identity,
    as many as the allocation table says."""
    out = tmp_path / "out"
    proc = run_cli("run", "multifidelity_rotor", "--out", str(out), cwd=tmp_path,
                   fresh=True)
    assert proc.returncode == 0, proc.stderr
    show = run_cli("show", str(out), "multifidelity", cwd=tmp_path)
    assert show.returncode == 0, show.stderr
    for text in ("Allocation (mfmc, 20-point pilot)", "Multi-fidelity estimates",
                 "HF runs plain MC needs (mean)", "coarse"):
        assert text in show.stdout
    html = "".join(p.read_text() for p in (out / "report").rglob("*.html"))
    assert "Allocation (mfmc" in html and "Multi-fidelity estimates" in html

    res = load_step(out / "steps" / "multifidelity")
    check_estimates(res, ["thrust", "power"])
    runs = [res.scalars["runs/model"], res.scalars["runs/coarse"]]
    assert sorted(store_counts(out).values()) == sorted(int(n) for n in runs)
    assert res.scalars["allocation/coarse"] > 10 * res.scalars["allocation/model"]


def test_a_dearer_mean_is_explained_by_what_the_run_measured(tmp_path):
    """A 60-point pilot before a 10-run budget: the multi-fidelity mean costs more than plain
    Monte Carlo, and the CLI's warning gives the cause from the saved record (the main phase's
    own saving and the pilot's share of the cost); with the main phase losing too (the same
    record with a poor cheap model), the cause is the correlation, and for a response other
    than the target, the allocation's target."""
    from dataclasses import replace

    from rotoruq.steps.multifidelity import MultifidelityRecord, multifidelity_warnings

    study = tmp_path / "mf.toml"
    study.write_text(ROTOR_STUDY.read_text().replace("budget = 200", "budget = 10")
                     .replace("n_pilot = 20", "n_pilot = 60"))
    out = tmp_path / "out"
    proc = run_cli("run", str(study), "--out", str(out), "--no-report", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    res = load_step(out / "steps" / "multifidelity")
    rec = MultifidelityRecord.read(res)
    for j, r in enumerate(rec.names_out):
        n_eq = rec.n_equivalent_hf[rec.statistics.index("mean"), j]
        saving = n_eq * rec.cost[0] / (rec.cost_pilot + rec.cost_main)
        main = n_eq * rec.cost[0] / rec.cost_main
        share = rec.cost_pilot / (rec.cost_pilot + rec.cost_main)
        assert saving < 1 < main and share > 0.8
        assert (f"{r}: the multi-fidelity mean costs {1 / saving:.2g} times what plain Monte "
                "Carlo on the high-fidelity model would for the same standard error (pilot "
                f"included): the main phase alone saves {main:.2g}x, and the pilot is "
                f"{share:.0%} of the step's cost") in proc.stdout

    poor = replace(rec, n_equivalent_hf=rec.n_equivalent_hf * 0.1,
                   correlation=np.array([[1.0, 1.0], [0.3, -0.45]]))
    arrays, meta = poor.parts()
    said = multifidelity_warnings(replace(res, arrays=arrays, meta={**res.meta, **meta}), {})
    main = rec.n_equivalent_hf[0] * 0.1 * rec.cost[0] / rec.cost_main
    assert said[0].endswith(f"the main phase alone costs {1 / main[0]:.2g}x plain Monte Carlo: "
                            "the cheap models used correlate with it at |rho| <= 0.30 on the "
                            "pilot")
    assert said[1].endswith(f"the main phase alone costs {1 / main[1]:.2g}x plain Monte Carlo: "
                            "the cheap models used correlate with it at |rho| <= 0.45 on the "
                            "pilot, and the allocation was made for thrust")


def test_a_pilot_too_small_is_in_the_steps_record_and_the_summary(tmp_path):
    """The estimator's own warning (a pilot of 8 points for 2 models, under the 13 its
    control-variate weights need) is saved with the step: the run's summary counts and
    prints it and `rotoruq show --json` lists it (it was printed once while the step ran and
    then lost: the summary said 0 warnings, found in a by-hand run of forward_flight --quick)."""
    import json

    from rotoruq.methods.mf_pilot import pilot_too_small

    study = tmp_path / "mf.toml"
    study.write_text(ROTOR_STUDY.read_text().replace("budget = 200", "budget = 20")
                     .replace("n_pilot = 20", "n_pilot = 8"))
    out = tmp_path / "out"
    proc = run_cli("run", str(study), "--out", str(out), "--no-report", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    expected = pilot_too_small(8, 2)
    assert expected is not None and "use n_pilot >= 13" in expected
    assert expected in proc.stdout
    assert "0 warning(s)" not in proc.stdout
    show = run_cli("show", str(out), "multifidelity", "--json", cwd=tmp_path)
    assert show.returncode == 0, show.stderr
    assert expected in json.loads(show.stdout)["steps"]["multifidelity"]["warnings"]


def test_the_allocation_note_names_the_responses_kept_as_evaluated(tmp_path):
    """With adapt = "linear", the allocation table's note lists the (model, response) pairs
    whose adaptation was not used, read from the saved record: none on the bundled study
    (the coarse grid's adaptation helps both responses), and power when its correlation is
    the model's own."""
    from dataclasses import replace

    from rotoruq.steps.multifidelity import MultifidelityRecord, multifidelity_tables

    study = tmp_path / "mf.toml"
    study.write_text(ROTOR_STUDY.read_text().replace("n_pilot = 20",
                                                     'n_pilot = 20\nadapt = "linear"'))
    out = tmp_path / "out"
    proc = run_cli("run", str(study), "--out", str(out), "--no-report", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    show = run_cli("show", str(out), "multifidelity", cwd=tmp_path)
    assert "the model's own is beside it.)" in show.stdout and "Kept as" not in show.stdout
    res = load_step(out / "steps" / "multifidelity")
    rec = MultifidelityRecord.read(res)
    assert np.all(rec.correlation[1] != rec.correlation_unadapted[1])
    corr = rec.correlation.copy()
    corr[1, 1] = rec.correlation_unadapted[1, 1]
    arrays, meta = replace(rec, correlation=corr).parts()
    note = multifidelity_tables(replace(res, arrays=arrays, meta={**res.meta, **meta}), {})[0]
    assert ("Kept as evaluated (the adaptation correlated worse, leave-one-out): coarse for "
            "power.") in str(note.note)


@pytest.mark.slow
def test_rotor_study_on_dask_by_changing_only_the_executor(tmp_path):
    """The same study file with ``[executor] kind = "dask"`` (a local cluster the run starts):
    it runs, and its estimates are as right as the serial ones."""
    pytest.importorskip("distributed")
    study = tmp_path / "mf.toml"
    study.write_text(ROTOR_STUDY.read_text() + '\n[executor]\nkind = "dask"\n')
    out = tmp_path / "out"
    proc = run_cli("run", str(study), "--out", str(out), "--no-report", cwd=tmp_path,
                   fresh=True)
    assert proc.returncode == 0, proc.stderr
    check_estimates(load_step(out / "steps" / "multifidelity"), ["thrust", "power"])


@pytest.mark.slow  # ~13 CPU-s; tests/test_multifidelity_sobol.py stays fast
def test_sobol_indices_of_a_multifidelity_step_through_the_cli(tmp_path):
    """``sobol = true`` in the study file: `rotoruq show` prints the multi-fidelity Sobol'
    table, and each index is within 4 of its standard errors (plus 0.01 for the reference's
    own error) of pick-freeze on the high-fidelity rotor with 2^13 Sobol'-sequence base
    samples."""
    import rotoruq as rq

    text = ROTOR_STUDY.read_text().replace("n_pilot = 20", "n_pilot = 20\nsobol = true")
    study = tmp_path / "mf_sobol.toml"
    study.write_text(text)
    out = tmp_path / "out"
    proc = run_cli("run", str(study), "--out", str(out), "--no-report", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    show = run_cli("show", str(out), "multifidelity", cwd=tmp_path)
    assert "Sobol' indices (multi-fidelity, mfmc)" in show.stdout, show.stdout
    res = load_step(out / "steps" / "multifidelity")
    assert res.meta["record"]["fields"]["sobol"] is True
    names = ["collective_deg", "cla_m03"]
    hf = RotorModel("gvpm", names_in=names, names_out=["thrust", "power"],
                    fixed={"height_over_radius": 4.0})
    space = rq.ParameterSpace({"collective_deg": rq.Uniform(4.5, 6.5),
                               "cla_m03": rq.Normal(0.1080, 5.4e-3)})
    ref = rq.sobol_indices(hf, space, 2**13, seed=1, n_bootstrap=0)
    for j, r in enumerate(["thrust", "power"]):
        for i, x in enumerate(names):
            for key, exact in (("main", ref.main), ("total", ref.total)):
                est = res.scalars[f"sobol_{key}/{r}/{x}"]
                se = res.scalars[f"sobol_{key}_se/{r}/{x}"]
                assert se > 0
                assert abs(est - float(exact[j, i])) < 4 * se + 0.01, (key, r, x, est,
                                                                      exact[j, i], se)


# ------------------------------------------------------------------------------------------
# the runner: named models, identities, factories


def small_study(tmp_path: Path, coarse: str = "n_stations = 3, n_azimuth = 6") -> Path:
    text = ROTOR_STUDY.read_text().replace("n_stations = 3, n_azimuth = 6", coarse)
    text = text.replace("budget = 200", "budget = 20").replace("n_pilot = 20", "n_pilot = 8")
    path = tmp_path / "mf.toml"
    path.write_text(text)
    return path


def test_a_changed_named_model_reruns_the_step_and_keeps_its_own_evaluations(tmp_path):
    """Changing [models.coarse] changes the step's identity (its spec and its model part);
    the new coarse model's runs are stored under a new identity, the old ones are not served
    for it, and [model]'s stored runs are reused."""
    path = small_study(tmp_path)
    out = tmp_path / "out"
    run_study(path, out=out)
    ids = set(store_counts(out))
    assert len(ids) == 2
    assert why_rerun(out)["multifidelity"] == []

    small_study(tmp_path, "n_stations = 4, n_azimuth = 8")
    reasons = why_rerun(out)["multifidelity"]
    assert any(r.startswith("spec") for r in reasons) and any(r.startswith("model")
                                                              for r in reasons), reasons
    second = run_study(path, out=out)
    assert second.reused == ()
    after = store_counts(out)
    new = set(after) - ids
    assert len(new) == 1 and len(after) == 3
    assert after[next(iter(new))] == int(second["multifidelity"].scalars["runs/coarse"])


def test_a_python_factory_without_named_models_is_told_so(tmp_path):
    def factory(inputs, responses, fixed):
        return RotorModel("gvpm", names_in=list(inputs), names_out=list(responses),
                          fixed=dict(fixed))

    with pytest.raises(ParameterError, match=r"named model 'coarse' needs a factory "
                       r"f\(inputs, responses, fixed, model=NAME\)"):
        run_study(small_study(tmp_path), out=tmp_path / "out", model_factory=factory)


def test_named_model_gets_the_study_operating_point_and_its_own_fixed(tmp_path):
    """A named model inherits [model]'s fixed inputs; its own `fixed` wins over them."""
    from rotoruq.study.runner import build_model

    text = ROTOR_STUDY.read_text().replace(
        "discretization = { n_stations = 3, n_azimuth = 6 }",
        "discretization = { n_stations = 3, n_azimuth = 6 }\nfixed = { rho = 1.1 }")
    path = tmp_path / "mf.toml"
    path.write_text(text)
    study = load_study(path)
    coarse = build_model(study, ["collective_deg"], ["thrust"],
                         {"height_over_radius": 4.0, "rho": 1.225}, model="coarse")
    assert coarse.fixed == {"height_over_radius": 4.0, "rho": 1.1}
    assert (coarse.grid.r.size, coarse.grid.psi.size) == (3, 6)
    hf = build_model(study, ["collective_deg"], ["thrust"], {"height_over_radius": 4.0})
    assert (hf.grid.r.size, hf.grid.psi.size) == (10, 36)


# ------------------------------------------------------------------------------------------
# bad input: the file, the line, what was expected

BASE = """\
[study]
name = "mf"

[model]
preset = "gvpm"
responses = ["thrust", "power"]
fixed = { height_over_radius = 4.0 }

[models.coarse]
preset = "gvpm"
discretization = { n_stations = 3, n_azimuth = 6 }

[parameters.collective_deg]
distribution = "uniform"
lower = 4.5
upper = 6.5

[[steps]]
type = "multifidelity"
models = ["coarse"]
budget = 10
"""


def line_of(text: str, needle: str) -> int:
    return next(i for i, line in enumerate(text.splitlines(), 1) if needle in line)


@pytest.mark.parametrize("old, new, marker, expected", [
    ('models = ["coarse"]', 'models = ["coarse", "fine"]', 'models = ["coarse", "fine"]',
     "names of [models.NAME] tables"),
    ('discretization = { n_stations = 3, n_azimuth = 6 }',
     'discretization = { n_stations = 3, n_azimuth = 6 }\nresponses = ["thrust"]',
     'responses = ["thrust"]', "include the study's responses (thrust, power); missing power"),
    ('discretization = { n_stations = 3, n_azimuth = 6 }',
     'discretization = { n_stations = 3, n_azimuth = 6 }\nrespones = ["thrust"]',
     "respones", "one of the keys of [models.coarse]"),
    ('discretization = { n_stations = 3, n_azimuth = 6 }',
     'discretization = { n_stations = 3, n_azimuth = 6 }\nfixed = { collective_deg = 5.0 }',
     "fixed = { collective_deg", "either fixed in [models.coarse] or uncertain"),
    ("n_azimuth = 6 }", "n_azimuth = 3 }", "n_azimuth = 3",
     "a discretization the rotor accepts (need at least 2 stations and 5 azimuth steps)"),
    ("n_azimuth = 6 }", "n_azimuth = 6, n_radial = 4 }", "n_radial",
     "one of the keys of [models.coarse] discretization"),
    ("[models.coarse]", "[models.model]", "[models.model]", "a model name"),
    ('discretization = { n_stations = 3, n_azimuth = 6 }',
     'command = ["python", "driver.py"]', 'command = ["python", "driver.py"]',
     "either preset or command in [models.coarse]"),
])
def test_bad_models_input_names_the_line(tmp_path, old, new, marker, expected):
    text = BASE.replace(old, new, 1)
    path = tmp_path / "mf.toml"
    path.write_text(text)
    with pytest.raises(InputFileError) as info:
        load_study(path)
    err = info.value
    assert err.path == str(path)
    assert err.line == line_of(text, marker), (err.line, str(err))
    assert expected in str(err), str(err)


def test_a_rotor_named_model_must_take_every_study_input(tmp_path):
    """An external [model] may take any input; a rotor [models.NAME] is evaluated at the same
    points and must accept each of them."""
    text = BASE.replace('preset = "gvpm"\nresponses', 'command = ["python", "solver.py"]\n'
                        'responses', 1).replace("[parameters.collective_deg]",
                                                "[parameters.web_thickness]")
    path = tmp_path / "mf.toml"
    path.write_text(text)
    with pytest.raises(InputFileError) as info:
        load_study(path)
    assert info.value.line == line_of(text, "[models.coarse]") + 1
    assert "'web_thickness' is not an input of [models.coarse]" in str(info.value)


def test_bad_models_input_through_the_cli(tmp_path, rotoruq_main, monkeypatch):
    # `rotoruq run` in this process: refused when the study is read
    text = BASE.replace('models = ["coarse"]', 'models = ["corse"]')
    (tmp_path / "mf.toml").write_text(text)
    monkeypatch.chdir(tmp_path)
    code, _, err = rotoruq_main("run", "mf.toml")
    assert code != 0
    assert f"mf.toml, line {line_of(text, 'corse')}" in err, err
    assert "(defined: coarse) (did you mean 'coarse'?), found 'corse'" in err


# ------------------------------------------------------------------------------------------
# the MBDyn study


def test_bundled_mbdyn_study_parses():
    study = load_study(STUDIES / "mbdyn_multifidelity.toml")
    assert study.model.kind == "external" and "elastic" in study.model.external.command
    assert study.models["builtin"].preset == "gvpm"
    assert "rigid" in study.models["rigid"].external.command
    assert [tuple(s.options["models"]) for s in study.steps] == [("builtin", "rigid"),
                                                                  ("builtin",)]


@pytest.mark.slow
@needs_mbdyn
def test_mbdyn_study_runs_through_the_cli(tmp_path):
    """`rotoruq run mbdyn_multifidelity --quick` with the real solver: both steps' allocation
    and estimate tables, finite estimates with standard errors, each model's runs (elastic,
    rigid, built-in) in the store under its own identity, as many as the allocation says.
    The run is at 1 thread for numba and BLAS; a second run at 2 threads and ``--jobs 2``
    replaying its MBDyn runs from a copy of its store saves the same bits (issue 35:
    test_reproducible_studies.py's check of this study)."""
    out = tmp_path / "out"
    env, starts = counting_mbdyn(tmp_path)
    env.update({k: "1" for k in THREAD_VARIABLES})
    proc = run_cli("run", "mbdyn_multifidelity", "--quick", "--out", str(out), cwd=tmp_path,
                   env=env, timeout=900, fresh=True)
    assert proc.returncode == 0, proc.stderr
    assert mbdyn_starts(starts) > 0
    show = run_cli("show", str(out), cwd=tmp_path)
    assert show.stdout.count("Multi-fidelity estimates") == 2
    assert "rigid" in show.stdout and "builtin" in show.stdout
    loads = load_step(out / "steps" / "loads")
    moments = load_step(out / "steps" / "hub_moments")
    for res, responses in ((loads, ["thrust", "power"]),
                           (moments, ["thrust", "power", "roll", "pitch"])):
        for r in responses:
            assert np.isfinite(res.scalars[f"mean/{r}"]) and res.scalars[f"mean_se/{r}"] > 0
        assert res.scalars["correlation/builtin/thrust"] > 0.9
    runs = [int(res.scalars[f"runs/{m}"]) for res in (loads, moments)
            for m in res.meta["models"]]
    # elastic and built-in at two operating points, rigid at one: five identities
    assert sorted(store_counts(out).values()) == sorted(runs)
    assert_replays_bitwise("mbdyn_multifidelity", out, tmp_path / "replay", env, starts)


@pytest.mark.slow
@pytest.mark.extended  # CI time (~80 s): MBDyn studies on Dask stay in CI through
# test_mbdyn.py::test_study_runs_on_dask_by_changing_only_the_executor
@needs_mbdyn
def test_mbdyn_study_on_dask_by_changing_only_the_executor(tmp_path):
    """The bundled MBDyn study with only ``[executor]`` changed to a Dask local cluster (the
    run starts it; MBDyn's drivers run on its workers), ``--quick``: both steps done, the
    same runs stored as the allocation says, and the report shows the allocation (adapted
    correlations), the estimates with standard errors and the HF runs plain MC needs."""
    pytest.importorskip("distributed")
    text = (STUDIES / "mbdyn_multifidelity.toml").read_text()
    assert text.count('kind = "processes"') == 1
    study = tmp_path / "mbdyn_mf_dask.toml"
    study.write_text(text.replace('kind = "processes"', 'kind = "dask"'))
    out = tmp_path / "out"
    proc = run_cli("run", str(study), "--quick", "--out", str(out), cwd=tmp_path,
                   env=env_with_mbdyn(), timeout=900, fresh=True)
    assert proc.returncode == 0, proc.stderr
    loads = load_step(out / "steps" / "loads")
    moments = load_step(out / "steps" / "hub_moments")
    for res in (loads, moments):
        assert res.meta["record"]["fields"]["adapt"] == "linear"
        for r in ("thrust", "power"):
            assert np.isfinite(res.scalars[f"mean/{r}"]) and res.scalars[f"mean_se/{r}"] > 0
            assert res.scalars[f"n_equivalent_hf/mean/{r}"] > 0
    runs = [int(res.scalars[f"runs/{m}"]) for res in (loads, moments)
            for m in res.meta["models"]]
    assert sorted(store_counts(out).values()) == sorted(runs)
    html = "".join(p.read_text() for p in (out / "report").rglob("*.html"))
    for text in ("Allocation (mfmc", "correlation with HF, adapted", "correlation with HF, own",
                 "Multi-fidelity estimates",
                 "mean std. error", "HF runs plain MC needs (mean)"):
        assert text in html, text


def test_measured_costs_of_a_pilot_served_from_the_store_are_the_models_costs(tmp_path):
    """A re-run whose pilot the store serves measures each model's cost from the seconds the
    stored runs took (not the lookup's), so the allocation does not change."""
    import time

    from rotoruq.evaluation.evaluator import Evaluator
    from rotoruq.methods.multifidelity import multifidelity_sample
    from rotoruq.model import FunctionModel
    from rotoruq.params import Normal, ParameterSpace

    def slow(per_row, shift):
        def f(x):
            time.sleep(per_row * len(x))
            return np.column_stack([x[:, 0] + shift * x[:, 1] ** 2])
        return f

    space = ParameterSpace([("a", Normal(0, 1)), ("b", Normal(0, 1))])
    costs = []
    for _ in range(2):
        models = [Evaluator(FunctionModel(slow(p, s), ["a", "b"], ["y"]), store=tmp_path / "s.db",
                            model_id=f"m{k}")
                  for k, (p, s) in enumerate(((0.004, 0.3), (0.0004, 0.25)))]
        res = multifidelity_sample(models, space, 40, budget_unit="hf_runs", n_pilot=12, seed=3)
        costs.append(np.asarray(res.costs))
    # first run: measured; second: all pilot rows from the store, same costs within timing noise
    assert costs[0][0] > 0.002 and costs[0][1] < costs[0][0] / 3
    assert np.all(costs[1] / costs[0] > 0.5) and np.all(costs[1] / costs[0] < 2.0), costs
