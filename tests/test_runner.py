"""The study runner on small analytic models: results match closed forms, are written to disk,
and a re-run reuses unchanged steps."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import numpy as np
import pytest

from rotoruq.model import FunctionModel
from rotoruq.results import load_results
from rotoruq.study.cli import main
from rotoruq.study.runner import run_study

# y1 = 2 a + 3 b + c ;  y2 = a - b     (c is a fixed input)
COEF = np.array([[2.0, 3.0], [1.0, -1.0]])


def linear_factory(calls: list | None = None):
    def factory(inputs, responses, fixed):
        def f(x):
            if calls is not None:
                calls.append(len(x))
            full = {n: x[:, i] for i, n in enumerate(inputs)}
            a = full.get("a", np.full(len(x), fixed.get("a", 0.0)))
            b = full.get("b", np.full(len(x), fixed.get("b", 0.0)))
            c = fixed.get("c", 0.0)
            y = {"y1": 2 * a + 3 * b + c, "y2": a - b}
            return np.column_stack([y[r] for r in responses])

        return FunctionModel(f, inputs, responses)

    return factory


STUDY = """\
[study]
name = "lin"
seed = 7

[model]
command = ["unused"]
responses = ["y1", "y2"]
fixed = { c = 1.0 }

[parameters.a]
distribution = "normal"
mean = 1.0
std = 0.1

[parameters.b]
distribution = "normal"
mean = 2.0
std = 0.2

[data.obs]
c = [1.0, 2.0]
y1 = [9.0, 10.5]
y2 = [-1.0, -1.0]

[[steps]]
name = "truth"
type = "sampling"
n_samples = 400
noise_std = { y1 = 0.5 }

[[steps]]
name = "mv"
type = "mean_value"

[[steps]]
name = "fit"
type = "least_squares"
data = "obs"
responses = ["y2"]
parameters = ["a"]

[[steps]]
name = "check"
type = "forward_check"
from = "fit.calibrated"
data = "obs"
n_samples = 300
sweep = { c = [1.0, 2.0] }
"""


def write(tmp_path: Path, text: str = STUDY) -> Path:
    p = tmp_path / "lin.toml"
    p.write_text(textwrap.dedent(text))
    return p


def test_run_linear_study(tmp_path):
    run = run_study(write(tmp_path), model_factory=linear_factory())
    assert run.out == tmp_path / "rotoruq-results" / "lin"
    truth = run["truth"]
    # exact: mean y1 = 2 + 6 + 1 = 9, std y1 = sqrt(0.04 + 0.36) ; LHS on 400 points
    assert truth.get("mean/y1") == pytest.approx(9.0, abs=0.01)
    assert truth.get("std/y1") == pytest.approx(np.sqrt(0.4), rel=0.03)
    noisy = truth.column("outputs", "y1") - truth.column("outputs_clean", "y1")
    assert np.std(noisy) == pytest.approx(0.5, rel=0.15)
    mv = run["mv"]  # linear model: mean value method is exact
    assert mv.get("mean/y1") == pytest.approx(9.0, rel=1e-9)
    assert mv.get("std/y2") == pytest.approx(np.sqrt(0.01 + 0.04), rel=1e-6)
    fit = run["fit"]  # y2 = a - b with b fixed at its mean 2: a = 1
    assert fit.get("value/a") == pytest.approx(1.0, abs=1e-6)
    assert set(fit.distributions) == {"a"}
    check = run["check"]
    # only `a` is uncertain now (b fixed at 2): y1 = 2a + 6 + c, sweep over c
    assert check.get("mean/y1@1") == pytest.approx(9.0, abs=0.02)
    assert check.get("mean/y1@2") == pytest.approx(10.0, abs=0.02)
    assert check.get("data/y1@2") == 10.5
    nstd = abs(10.5 - check.get("mean/y1@2")) / check.get("std/y1@2")
    assert check.get("nstd/y1@2") == pytest.approx(nstd)
    # written to disk and read back identically
    saved = load_results(run.out)
    assert list(saved) == ["truth", "mv", "fit", "check"]
    assert saved["check"].scalars == pytest.approx(dict(check.scalars))
    np.testing.assert_array_equal(saved["truth"].arrays["inputs"], truth.arrays["inputs"])
    header = (run.out / "steps" / "truth" / "inputs.csv").read_text().splitlines()[0]
    assert header == "a,b"
    assert json.loads((run.out / "study.json").read_text())["steps"][0] == "truth"


def test_rerun_reuses_and_redoes_what_changed(tmp_path):
    path = write(tmp_path)
    calls: list = []
    first = run_study(path, model_factory=linear_factory(calls))
    n_first = sum(calls)
    calls.clear()
    again = run_study(path, model_factory=linear_factory(calls))
    assert sum(calls) == 0 and set(again.reused) == {"truth", "mv", "fit", "check"}
    assert again["truth"].scalars == first["truth"].scalars
    # change the last step only: the others are reused
    path.write_text(STUDY.replace("n_samples = 300", "n_samples = 200"))
    third = run_study(path, model_factory=linear_factory(calls))
    assert set(third.reused) == {"truth", "mv", "fit"}
    assert 0 < sum(calls) < n_first


def test_same_seed_same_numbers(tmp_path):
    a = run_study(write(tmp_path), out=tmp_path / "a", model_factory=linear_factory())
    b = run_study(write(tmp_path), out=tmp_path / "b", model_factory=linear_factory())
    assert a["truth"].scalars == b["truth"].scalars


def test_quick_reduces_samples(tmp_path):
    run = run_study(write(tmp_path), quick=True, model_factory=linear_factory())
    assert run["truth"].arrays["inputs"].shape == (40, 2)
    assert run["check"].arrays["outputs@1"].shape == (40, 2)


def test_cli_run_reports_study_errors(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[study]\nname = 1\n")
    assert main(["run", str(bad)]) == 1
    err = capsys.readouterr().err
    assert f"{bad}, line 2: expected 'name' of [study] to be a string" in err


METHODS = """\
[study]
name = "methods"
seed = 3

[model]
command = ["unused"]
responses = ["y1", "y2"]

[parameters.a]
distribution = "normal"
mean = 1.0
std = 0.1

[parameters.b]
distribution = "normal"
mean = 2.0
std = 0.2

[data.obs]
y2 = [-1.0, -1.0]

[[steps]]
name = "sobol"
type = "sensitivity"
responses = ["y1"]
n_samples = 4000

[[steps]]
name = "pce"
type = "pce"
order = 1

[[steps]]
name = "form"
type = "reliability"
responses = ["y1"]
response_levels = { y1 = [8.0, 8.6324555320336759] }

[[steps]]
name = "bayes"
type = "bayes_calibration"
parameters = ["a"]
responses = ["y2"]
emulator = "none"
noise_std = 0.1
n_samples = 6000
burn_in = 500

[steps.distributions.a]
distribution = "uniform"
lower = 0.0
upper = 2.0

[[steps]]
name = "cuu"
type = "cuu"
from = "bayes.posterior"
parameters = ["a"]
responses = ["y2"]
targets = { y2 = [-1.0, 0.3] }

[[steps]]
name = "ds"
type = "evidence"
responses = ["y2"]
intervals = { a = [[0.0, 1.0, 0.5], [1.0, 2.0, 0.5]] }
response_levels = { y2 = [-1.5] }
n_samples = 10
"""


def test_every_method_step_on_a_linear_model(tmp_path):
    p = tmp_path / "methods.toml"
    p.write_text(METHODS)
    run = run_study(p, model_factory=linear_factory())
    # y1 = 2a + 3b + 0: Var = 0.04 + 0.36; S_a = 0.1, S_b = 0.9 (additive: S = T)
    s = run["sobol"]
    assert s.get("S/y1/a") == pytest.approx(0.1, abs=0.05)
    assert s.get("T/y1/b") == pytest.approx(0.9, abs=0.05)
    pce = run["pce"]  # order 1 on a linear model: exact
    assert pce.get("mean/y1") == pytest.approx(8.0, rel=1e-10)
    assert pce.get("std/y1") == pytest.approx(np.sqrt(0.4), rel=1e-8)
    assert pce.get("S/y1/a") == pytest.approx(0.1, rel=1e-8)
    form = run["form"]  # linear-normal: FORM exact, P(y1 <= mean) = 0.5, mean + std -> Phi(1)
    assert form.get("cdf_probability/y1/0") == pytest.approx(0.5, abs=1e-6)
    assert form.get("cdf_probability/y1/1") == pytest.approx(0.841344746, abs=1e-5)
    bayes = run["bayes"]  # y2 = a - 2 observed twice at -1 with sigma 0.1: N(1, 0.1/sqrt 2)
    assert bayes.get("mean/a") == pytest.approx(1.0, abs=0.02)
    assert bayes.get("std/a") == pytest.approx(0.1 / np.sqrt(2), rel=0.25)
    assert bayes.distributions["a"]["kind"] == "normal"
    cuu = run["cuu"]  # std(y2) = std(a) -> 0.3
    assert cuu.get("std/a") == pytest.approx(0.3, rel=1e-3)
    assert cuu.get("initial_std/a") == pytest.approx(bayes.get("std/a"))
    ds = run["ds"]  # cell [0, 1] gives y2 in [-2, -1]: Bel(y2 <= -1.5) = 0, Pl = 0.5
    assert ds.get("cbf/y2/0") == pytest.approx(0.0)
    assert ds.get("cpf/y2/0") == pytest.approx(0.5)


# A step type outside rotoruq: one module (below) and one registry line (an entry point in the
# group "rotoruq.steps"; a test installs it as a dist-info folder on the path).
CORNERS_MODULE = '''\
"""Step type ``corners``: the model at the 2^d corners mean +- k std of the inputs."""

import numpy as np

from rotoruq.model import evaluate
from rotoruq.render.tables import make_table, responses, value
from rotoruq.results import StepResult
from rotoruq.steps.base import StepType
from rotoruq.steps.options import Option, integer


def run_corners(ctx):
    k = ctx.options["k"]
    mean = np.array([d.mean for d in ctx.space.distributions])
    std = np.array([d.std for d in ctx.space.distributions])
    signs = np.array(np.meshgrid(*[[-1.0, 1.0]] * ctx.space.dim)).reshape(ctx.space.dim, -1).T
    y = np.asarray(evaluate(ctx.model(), mean + k * signs * std).values)
    scalars = {f"{w}/{r}": float(f(y[:, j])) for j, r in enumerate(ctx.responses)
               for w, f in (("min", np.min), ("max", np.max))}
    return StepResult(ctx.name, ctx.type, scalars, meta={"n_evaluations": len(signs)})


def corner_tables(res, labels):
    return [make_table("Corner extremes", ("response", "min", "max"),
                       [(r, value(res, f"min/{r}"), value(res, f"max/{r}"))
                        for r in responses(res)])]


def corner_warnings(res, labels):
    return [f"{res.name}: only {res.meta['n_evaluations']} corners"]


STEP = StepType("corners", run_corners, options={"k": Option(integer(1), 3)},
                tables=corner_tables, warnings=corner_warnings)
'''


def install_step_plugin(folder: Path) -> dict[str, str]:
    """The corners step type as a plugin in ``folder``; returns the environment that finds
    it (``PYTHONPATH``)."""
    import os

    folder.mkdir(parents=True, exist_ok=True)
    (folder / "corners_step.py").write_text(CORNERS_MODULE)
    info = folder / "corners_step-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: corners-step\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text("[rotoruq.steps]\ncorners = corners_step:STEP\n")
    path = [str(folder), os.environ.get("PYTHONPATH", "")]
    return {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in path if p)}


def test_a_new_step_type_is_one_file_and_one_registry_line(tmp_path):
    """A step type written outside rotoruq (one module, one entry point) is validated in
    study files, run through the command line, saved, rendered in the report and shown by
    ``rotoruq show``; a typo in its options is caught with the closest key."""
    import subprocess
    import sys

    from test_trust import external_study

    env = install_step_plugin(tmp_path / "plugin")
    study = external_study(tmp_path / "s", c=1.0)
    study.write_text(study.read_text() + '\n[[steps]]\nname = "corners"\ntype = "corners"\n'
                     "k = 2\n")
    cli = [sys.executable, "-m", "rotoruq.study.cli"]
    out = tmp_path / "out"
    run = subprocess.run([*cli, "run", str(study), "--out", str(out)], capture_output=True,
                         text=True, env=env, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    assert "corners              corners" in run.stdout
    res = load_results(out)["corners"]
    # y1 = 2a + 3b + c with a ~ U(0, 1) (mean 0.5, std 1/sqrt(12)), b ~ N(2, 0.5), c = 1:
    # corners at mean +- 2 std
    sa, sb = 2 / np.sqrt(12.0), 2 * 0.5
    assert res.get("max/y1") == pytest.approx(2 * (0.5 + sa) + 3 * (2 + sb) + 1, rel=1e-12)
    assert res.get("min/y2") == pytest.approx((0.5 - sa) - (2 + sb), rel=1e-12)
    assert res.meta["n_evaluations"] == 4 and res.meta["options"] == {"k": 2}
    page = (out / "report" / "index.html").read_text()
    assert "Corner extremes" in page and "only 4 corners" in page
    show = subprocess.run([*cli, "show", str(out), "corners"], capture_output=True, text=True,
                          env=env, timeout=120)
    assert show.returncode == 0, show.stderr
    assert "== corners (corners)" in show.stdout and "Corner extremes" in show.stdout
    assert f"{res.get('max/y1'):.4g}"[:4] in show.stdout
    # without the plugin (this process does not have it: tests/_inproc.py) the type is
    # unknown, and the error lists the known ones
    from _inproc import rotoruq

    bad = rotoruq("run", study, "--out", tmp_path / "o2")
    assert bad.returncode != 0 and "a step type among sampling, sensitivity" in bad.stderr
    typo = study.read_text().replace("k = 2", "kk = 2")
    study.write_text(typo)
    bad = subprocess.run([*cli, "run", str(study), "--out", str(tmp_path / "o3")],
                         capture_output=True, text=True, env=env, timeout=120)
    assert bad.returncode != 0 and "did you mean 'k'" in bad.stderr


def test_cli_progress_is_logging(tmp_path):
    """Progress lines reach stderr through logging; --quiet keeps only warnings."""
    from _inproc import rotoruq

    study = tmp_path / "mv.toml"
    study.write_text(textwrap.dedent("""\
        [study]
        name = "mv"

        [model]
        preset = "gvpm"
        responses = ["thrust"]
        fixed = { collective_deg = 5.4, height_over_radius = 4.0 }

        [parameters.cla_m03]
        distribution = "normal"
        mean = 0.108
        std = 5.4e-3

        [[steps]]
        name = "mv"
        type = "mean_value"
        """))
    # through the CLI's entry point in this process (tests/_inproc.py): the logging it
    # configures writes to this process's stderr, captured there
    loud = rotoruq("run", study, "--out", tmp_path / "a", "--no-report")
    assert loud.returncode == 0, loud.stderr
    assert "[mv] 1/1 mv: running mean_value (cla_m03 -> thrust)" in loud.stderr
    assert "[mv] 1/1 mv: done in" in loud.stderr
    quiet = rotoruq("--quiet", "run", study, "--out", tmp_path / "b", "--no-report")
    assert quiet.returncode == 0, quiet.stderr
    assert "running" not in quiet.stderr and "done in" not in quiet.stderr
    assert quiet.stdout == "" and quiet.stderr == ""  # --quiet: errors only


def test_identities_cover_only_the_code_that_computes_the_answer():
    """A rotor model's identity digests the rotor and its airfoil data; an external model's,
    the evaluation layer's file contract; a step's, its step module and its methods."""
    from rotoruq.evaluation.identity import EPOCHS, code_parts

    external = code_parts(["rotoruq.evaluation.external"])
    assert "rotoruq/evaluation/dakota_files.py" in external
    assert not [k for k in external if "/methods/" in k or "/steps/" in k or "/rotor/" in k]
    rotor = code_parts(["rotoruq.rotor.model"])
    assert "rotoruq/rotor/_kernel.py" in rotor and "rotoruq/data/airfoils/naca0012.c81" in rotor
    assert not [k for k in rotor if "/methods/" in k or "/evaluation/" in k]
    pce = code_parts(["rotoruq.steps.pce"])
    assert {"rotoruq/steps/pce.py", "rotoruq/methods/pce.py"} <= set(pce)
    assert "rotoruq/methods/mcmc/bayes.py" not in pce and "rotoruq/report/html.py" not in pce
    assert pce["epoch:methods"] == str(EPOCHS["methods"])
    # calibration under uncertainty may run a PCE inside: its fingerprint covers pce.py
    assert "rotoruq/methods/pce.py" in code_parts(["rotoruq.steps.cuu"])


@pytest.mark.slow  # ~9-10 CPU-s: six fresh processes on a copy of the package; the
# fingerprint's modules stay in the fast lane (the test after it, and the one before)
def test_editing_a_method_reruns_only_its_steps(tmp_path):
    """Append a comment to methods/pce.py in a copy of the package: the pce step runs again
    (``show --why-rerun`` names the file), the other steps are reused and every evaluation of
    the external model comes from the store (its identity does not include the methods)."""
    import os
    import shutil
    import subprocess
    import sys

    from test_trust import external_study

    pkg = tmp_path / "pkg"
    shutil.copytree(Path(__file__).resolve().parents[1] / "src" / "rotoruq", pkg / "rotoruq",
                    ignore=shutil.ignore_patterns("__pycache__"))
    log = tmp_path / "evaluations.log"
    env = {**os.environ, "PYTHONPATH": str(pkg), "DRIVER_LOG": str(log)}
    study = external_study(tmp_path / "s", n=6)
    study.write_text(study.read_text() + textwrap.dedent("""
        [[steps]]
        name = "chaos"
        type = "pce"
        order = 2

        [[steps]]
        name = "mv"
        type = "mean_value"
        """))
    out = tmp_path / "out"

    def cli(*args):
        proc = subprocess.run([sys.executable, "-m", "rotoruq.study.cli", *map(str, args)],
                              capture_output=True, text=True, env=env, timeout=300)
        assert proc.returncode == 0, proc.stderr[-3000:]
        return proc.stdout

    where = subprocess.run([sys.executable, "-c", "import rotoruq; print(rotoruq.__file__)"],
                           capture_output=True, text=True, env=env, check=True).stdout
    assert where.strip() == str(pkg / "rotoruq" / "__init__.py")
    cli("run", study, "--out", out, "--no-report")
    n_first = len(log.read_text().splitlines())
    first = load_results(out)
    # 6 LHS points, 3 x 3 quadrature nodes, the mean-value gradient (its centre point is a
    # quadrature node, served by the store)
    assert n_first == 6 + 9 + first["mv"].meta["n_evaluations"] - 1
    assert cli("show", out, "--why-rerun").count(": reused") == 3
    with open(pkg / "rotoruq" / "methods" / "pce.py", "a") as fh:
        fh.write("\n# an edit that changes no number\n")
    why = cli("show", out, "--why-rerun")
    assert "chaos: runs again: code: rotoruq/methods/pce.py changed" in why, why
    assert "lhs: reused" in why and "mv: reused" in why, why
    summary = cli("run", study, "--out", out, "--no-report")
    rows = {line.split()[0]: line for line in summary.splitlines()
            if line.startswith("  ") and not line.startswith("     ")}
    assert "reused" in rows["lhs"] and "reused" in rows["mv"], summary
    assert "reused" not in rows["chaos"], summary
    assert len(log.read_text().splitlines()) == n_first  # every evaluation from the store
    again = load_results(out)["chaos"]
    assert again.fingerprint != first["chaos"].fingerprint
    assert again.scalars == first["chaos"].scalars


def test_the_modules_a_step_type_lists_enter_its_fingerprint_only(tmp_path, monkeypatch):
    """``StepType.modules`` is true: a module listed by one step type (and not imported by its
    adapter) is in that type's code part; editing it changes that type's step code and no
    other type's."""
    import dataclasses

    from rotoruq.evaluation.identity import code_digest
    from rotoruq.steps import step_type as registered
    from rotoruq.study import runner

    for name in ("helper_a", "helper_b"):
        (tmp_path / f"{name}.py").write_text(f'"""{name}."""\nK = 1\n')
    monkeypatch.syspath_prepend(str(tmp_path))
    types = {"a": dataclasses.replace(registered("mean_value"), name="a", modules=("helper_a",)),
             "b": dataclasses.replace(registered("mean_value"), name="b", modules=("helper_b",)),
             "c": dataclasses.replace(registered("mean_value"), name="c", modules=())}
    monkeypatch.setattr(runner, "step_type", types.__getitem__)
    before = {k: runner.step_code_parts(k) for k in types}
    assert [k for k in before["a"] if "helper" in k] == [str(tmp_path / "helper_a.py")]
    assert not [k for k in before["c"] if "helper" in k]
    assert before["c"]["rotoruq/steps/mean_value.py"] == before["a"]["rotoruq/steps/mean_value.py"]
    (tmp_path / "helper_a.py").write_text('"""helper_a, edited."""\nK = 2\n')
    after = {k: runner.step_code_parts(k) for k in types}
    assert code_digest(after["a"]) != code_digest(before["a"])
    assert code_digest(after["b"]) == code_digest(before["b"])
    assert code_digest(after["c"]) == code_digest(before["c"])
    # the built-in types' lists are in their code parts
    monkeypatch.undo()
    for st in (registered(n) for n in ("pce", "multifidelity", "reliability")):
        parts = runner.step_code_parts(st.name)
        for module in st.modules:
            assert "rotoruq/" + module.split(".", 1)[1].replace(".", "/") + ".py" in parts


WHY_STUDY = textwrap.dedent("""
    [study]
    name = "why"
    seed = 5

    [model]
    function = "text_book"
    responses = ["y1"]

    [parameters.a]
    distribution = "uniform"
    lower = -1.0
    upper = 1.0

    [parameters.b]
    distribution = "uniform"
    lower = -1.0
    upper = 1.0

    [[steps]]
    name = "lhs"
    type = "sampling"
    n_samples = 8

    [[steps]]
    name = "chaos"
    type = "pce"
    order = 2
    """)


def test_why_rerun_names_the_changed_key_with_its_old_and_new_value(tmp_path):
    """`rotoruq show --why-rerun` after one option of one step changed: the reason names the
    key and both values, computed from the saved result (found in a by-hand run: it said
    only "the step's table in the study file, its options, seed, position or --quick")."""
    from rotoruq.study.runner import why_rerun

    study = tmp_path / "why.toml"
    study.write_text(WHY_STUDY)
    run_study(study, out=tmp_path / "out")
    assert why_rerun(tmp_path / "out") == {"lhs": [], "chaos": []}
    study.write_text(WHY_STUDY.replace("order = 2", "order = 3").replace(
        'name = "lhs"', 'name = "lhs"\ntitle = "my design"'))
    assert why_rerun(tmp_path / "out") == {
        "lhs": ['spec: title "" -> "my design" changed'],
        "chaos": ["spec: order 2 -> 3 changed"]}
