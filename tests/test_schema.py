"""Study files: valid files load into dataclasses; every broken file gives an error that names
the file, the line and the expected form."""

from __future__ import annotations

import re
import textwrap
from pathlib import Path

import numpy as np
import pytest

from rotoruq.errors import InputFileError
from rotoruq.params import Normal, Uniform
from rotoruq.study.locator import Locator
from rotoruq.study.schema import load_study

VALID = """\
[study]
name = "demo"
seed = 3

[model]
preset = "gvpm"
responses = ["thrust", "power"]
fixed = { collective_deg = 5.4, height_over_radius = 4.0 }

[parameters.cla_m03]
distribution = "normal"
mean = 0.108
std = 5.4e-3

[parameters.k_pitch_link]
distribution = "uniform"
lower = 10
upper = 20

[data.measured]
file = "loads.csv"

[[steps]]
name = "bayes"
type = "bayes_calibration"
n_samples = 2000
burn_in = 100

[[steps]]
name = "fwd"
type = "forward_check"
from = "bayes.posterior"
data = "measured"
n_samples = 50
"""

CSV = "height_over_radius,thrust,power\n4,25.68,350.9\n2,29.0,399.4\n"


def write(tmp_path: Path, text: str, name: str = "study.toml") -> Path:
    (tmp_path / "loads.csv").write_text(CSV)
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return p


def error_of(tmp_path: Path, text: str) -> InputFileError:
    p = write(tmp_path, text)
    with pytest.raises(InputFileError) as info:
        load_study(p)
    err = info.value
    assert str(p) in str(err)
    return err


def line_of(text: str, needle: str) -> int:
    for no, line in enumerate(text.splitlines(), start=1):
        if needle in line:
            return no
    raise AssertionError(needle)


def test_valid_study_loads(tmp_path):
    study = load_study(write(tmp_path, VALID))
    assert study.info.name == "demo" and study.info.seed == 3
    assert study.info.output == tmp_path / "rotoruq-results" / "demo"
    assert study.model.kind == "preset" and study.model.preset == "gvpm"
    assert study.model.fixed == {"collective_deg": 5.4, "height_over_radius": 4.0}
    assert study.parameter_names == ("cla_m03", "k_pitch_link")
    assert study.parameters[0].distribution == Normal(0.108, 5.4e-3)
    assert study.parameters[1].distribution == Uniform(10.0, 20.0)
    np.testing.assert_allclose(study.data["measured"].columns["thrust"], [25.68, 29.0])
    bayes, fwd = study.steps
    assert bayes.data == "measured"  # the only data set is the default for calibration
    assert bayes.options["n_samples"] == 2000 and bayes.options["sampler"] == "dram"
    assert fwd.source == ("bayes", "posterior")
    assert fwd.line == line_of(VALID, "[[steps]]") + 6
    space = study.space()
    assert space.names == ("cla_m03", "k_pitch_link")


def test_data_select_and_inline(tmp_path):
    text = VALID.replace('file = "loads.csv"', 'file = "loads.csv"\nselect = '
                         '{ height_over_radius = 2 }')
    study = load_study(write(tmp_path, text))
    np.testing.assert_allclose(study.data["measured"].columns["power"], [399.4])
    text = VALID.replace('file = "loads.csv"', "thrust = [1.0, 2.0]\npower = [3.0, 4.0]")
    study = load_study(write(tmp_path, text))
    np.testing.assert_allclose(study.data["measured"].matrix(["power", "thrust"]),
                               [[3, 1], [4, 2]])


def test_bad_toml_names_line(tmp_path):
    text = VALID.replace("seed = 3", "seed = = 3")
    err = error_of(tmp_path, text)
    assert err.line == line_of(text, "seed = = 3")
    assert "expected valid TOML" in str(err)
    assert f"line {err.line}" in str(err)


def test_unknown_step_type_suggests(tmp_path):
    text = VALID.replace('type = "bayes_calibration"', 'type = "bayes_calibraton"')
    err = error_of(tmp_path, text)
    assert err.line == line_of(text, "bayes_calibraton")
    assert "did you mean 'bayes_calibration'?" in str(err)
    assert "a step type among sampling, sensitivity" in str(err)


def test_unknown_parameter_not_a_model_input(tmp_path):
    text = VALID.replace("[parameters.k_pitch_link]", "[parameters.k_pitch_lnk]")
    err = error_of(tmp_path, text)
    assert err.line == line_of(text, "[parameters.k_pitch_lnk]")
    assert "an input of the rotor model" in str(err)
    assert "did you mean 'k_pitch_link'?" in str(err)


def test_missing_data_file(tmp_path):
    text = VALID.replace("loads.csv", "missing.csv")
    err = error_of(tmp_path, text)
    assert err.line == line_of(text, "missing.csv")
    assert "an existing CSV file" in str(err) and "missing.csv" in str(err)


def test_negative_std(tmp_path):
    text = VALID.replace("std = 5.4e-3", "std = -5.4e-3")
    err = error_of(tmp_path, text)
    assert err.line == line_of(text, "std = -5.4e-3")
    assert "a valid normal distribution (mean = <number>, std = <number>)" in str(err)
    assert "std must be a finite number > 0" in str(err)


def test_circular_from(tmp_path):
    text = VALID.replace('n_samples = 2000', 'n_samples = 2000\nfrom = "fwd.posterior"')
    text = text.replace('type = "forward_check"', 'type = "bayes_calibration"')
    text = text.replace("n_samples = 50", "")
    err = error_of(tmp_path, text)
    assert err.line == line_of(text, 'from = "fwd.posterior"')
    assert "circular reference bayes -> fwd -> bayes" in str(err)


def test_forward_reference(tmp_path):
    text = VALID.replace('n_samples = 2000', 'n_samples = 2000\nfrom = "later.posterior"')
    text += '\n[[steps]]\nname = "later"\ntype = "bayes_calibration"\n'
    err = error_of(tmp_path, text)
    assert "a reference to an earlier step; 'later' is step #3" in str(err)
    assert err.line == line_of(text, "later.posterior")


def test_from_needs_a_posterior(tmp_path):
    text = VALID.replace('from = "bayes.posterior"', 'from = "bayes.calibrated"')
    err = error_of(tmp_path, text)
    assert "with <attr> one of posterior" in str(err)


def test_unknown_key_suggests_closest(tmp_path):
    text = VALID.replace("n_samples = 2000", "n_sample = 2000")
    err = error_of(tmp_path, text)
    assert err.line == line_of(text, "n_sample = 2000")
    assert "did you mean 'n_samples'?" in str(err)
    assert err.found == "n_sample"
    text = VALID.replace("seed = 3", "sed = 3")
    err = error_of(tmp_path, text)
    assert err.line == 3 and "did you mean 'seed'?" in str(err)


def test_wrong_option_type(tmp_path):
    text = VALID.replace("n_samples = 50", 'n_samples = "many"')
    err = error_of(tmp_path, text)
    assert err.line == line_of(text, 'n_samples = "many"')
    assert "'n_samples' of step 'fwd' (forward_check) to be an integer >= 1" in str(err)


def test_unknown_response_and_fixed_input(tmp_path):
    err = error_of(tmp_path, VALID.replace('"thrust", "power"', '"thrust", "powr"'))
    assert "did you mean 'power'?" in str(err) and err.line == 7
    err = error_of(tmp_path, VALID.replace("collective_deg = 5.4", "colective_deg = 5.4"))
    assert "did you mean 'collective_deg'?" in str(err) and err.line == 8


def test_step_parameters_must_exist(tmp_path):
    text = VALID.replace("n_samples = 50", 'n_samples = 50\nparameters = ["cla_m03", "kp"]')
    err = error_of(tmp_path, text)
    assert err.line == line_of(text, 'parameters = ["cla_m03", "kp"]')
    assert "names from [parameters] (cla_m03, k_pitch_link)" in str(err)


def test_external_model_accepts_any_names(tmp_path):
    text = VALID.replace('preset = "gvpm"', 'command = ["python", "driver.py"]\ntimeout = 30')
    text = text.replace("[parameters.k_pitch_link]", "[parameters.anything]")
    text = text.replace("fixed = { collective_deg = 5.4, height_over_radius = 4.0 }", "")
    study = load_study(write(tmp_path, text))
    assert study.model.kind == "external"
    assert study.model.external.command == ("python", "driver.py")
    assert study.model.external.timeout == 30.0


def test_missing_study_file(tmp_path):
    with pytest.raises(InputFileError, match=re.escape("expected an existing study file")):
        load_study(tmp_path / "nope.toml")


def test_locator_paths():
    text = '[a]\nx = 1\n[[s]]\nname = "p"\nq = { r = 2 }\n[[s]]\nname = "z"\n[b."c"]\nk = 3\n'
    loc = Locator(text)
    assert loc.line("a", "x") == 2
    assert loc.line("s", 0, "q", "r") == 5
    assert loc.line("s", 1, "name") == 7
    assert loc.line("s", 1, "missing") == 6
    assert loc.line("b", "c", "k") == 9


def test_bundled_studies_load():
    from rotoruq.study.cmd_reproduce import studies_dir

    root = studies_dir()
    files = sorted(root.glob("*.toml"))
    assert {f.name for f in files} >= {"validation.toml", "experiment.toml", "quick.toml"}
    for f in files:
        study = load_study(f)
        assert study.steps


def test_airfoil_inputs_are_the_rotors(tmp_path):
    """Airfoil coefficient names are checked by the rotor's own list: cla_m075 is valid
    when the preset's airfoil is fitted at Mach 0.75, and rejected (file, line, the valid
    names) when it is not; bo105's airfoil fits no drag, so cd0_m03 is not an input."""
    fitted = VALID.replace('fixed = { collective_deg = 5.4, height_over_radius = 4.0 }',
                           'fixed = { collective_deg = 5.4, height_over_radius = 4.0 }\n'
                           'preset_options = { airfoil_fit_machs = [0.3, 0.75] }')
    fitted = fitted.replace("[parameters.k_pitch_link]", "[parameters.cla_m075]")
    fitted = fitted.replace("lower = 10\nupper = 20", "lower = 0.1\nupper = 0.12")
    study = load_study(write(tmp_path, fitted))
    assert study.parameter_names == ("cla_m03", "cla_m075")
    text = VALID.replace("[parameters.k_pitch_link]", "[parameters.cla_m075]")
    err = error_of(tmp_path, text)
    assert err.line == line_of(text, "[parameters.cla_m075]")
    assert "an input of the rotor model 'gvpm'" in str(err) and "cla_m04" in str(err)
    text = VALID.replace('preset = "gvpm"', 'preset = "bo105"')
    text = text.replace("[parameters.k_pitch_link]", "[parameters.cd0_m03]")
    err = error_of(tmp_path, text)
    assert err.found == "cd0_m03" and "cl0_m03" in str(err)


def test_option_defaults_are_the_methods(tmp_path):
    """A key a study file leaves out takes the default of the method's own parameter (its
    signature), so a study and a Python call agree; every such parameter exists."""
    import inspect

    from rotoruq.steps import STEP_TYPES
    from rotoruq.study.options import REQUIRED, SIGNATURE, signature_default

    for st in STEP_TYPES.values():
        for key, opt in st.options.items():
            if opt.default is SIGNATURE:
                signature_default(opt.method or st.method, opt.param or key)  # no LookupError
    from rotoruq.methods.mcmc import ChainOptions, calibrate_bayes
    from rotoruq.methods.sensitivity import sobol_indices

    text = VALID + '\n[[steps]]\nname = "sens"\ntype = "sensitivity"\nn_samples = 64\n'
    study = load_study(write(tmp_path, text))
    sens = study.step("sens").options
    sig = inspect.signature(sobol_indices).parameters
    opts = STEP_TYPES["sensitivity"].options
    assert sens["design"] == sig[opts["design"].param or "design"].default
    assert sens["estimator"] == sig[opts["estimator"].param or "estimator"].default
    bayes = study.step("bayes").options
    # calibrate_bayes takes its chain settings as a ChainOptions record (issue 33)
    chains = ChainOptions()
    assert "chains" in inspect.signature(calibrate_bayes).parameters
    assert bayes["burn_in"] == 100  # given in the file
    no_burn = load_study(write(tmp_path, VALID.replace("burn_in = 100\n", "")))
    assert no_burn.step("bayes").options["burn_in"] == chains.burn_in
    assert bayes["sampler"] == chains.sampler
    # a method parameter without default is required in the study file
    assert STEP_TYPES["pce"].default("order") is REQUIRED
    err = error_of(tmp_path, VALID + '\n[[steps]]\nname = "pc"\ntype = "pce"\n')
    assert "to define 'order'" in str(err)


def test_pce_points_only_for_regression(tmp_path):
    text = VALID + '\n[[steps]]\nname = "pc"\ntype = "pce"\norder = 2\nn_samples = 40\n'
    err = error_of(tmp_path, text)
    assert err.line == line_of(text, "n_samples = 40")
    assert 'n_samples only with estimator = "regression"' in str(err)
    study = load_study(write(tmp_path, text.replace("n_samples = 40",
                                                    'n_samples = 40\nestimator = "regression"')))
    assert study.step("pc").options["n_samples"] == 40


def test_quick_overrides_are_options_of_the_step(tmp_path):
    text = VALID.replace("n_samples = 50", "n_samples = 50\nquick = { n = 5 }")
    err = error_of(tmp_path, text)
    assert err.found == "n" and "keys of quick = {...} of step 'fwd'" in str(err)
    assert err.line == line_of(text, "quick = { n = 5 }")
    err = error_of(tmp_path, text.replace("{ n = 5 }", "{ n_samples = 0 }"))
    assert "to be an integer >= 1" in str(err)
    study = load_study(write(tmp_path, text.replace("{ n = 5 }", "{ n_samples = 5 }")))
    assert study.step("fwd").quick == {"n_samples": 5}


def test_cli_names_the_new_word_for_an_old_key(tmp_path):
    """The user's path: ``rotoruq run`` on a study with a key from before the vocabulary
    (``chain_samples``) fails with the file, the line and the key it expected."""
    from _inproc import rotoruq  # the CLI's entry point, in this process

    text = VALID.replace("n_samples = 2000", "chain_samples = 2000")
    p = write(tmp_path, text)
    proc = rotoruq("run", p)
    assert proc.returncode == 1
    assert f"{p}, line {line_of(text, 'chain_samples')}" in proc.stderr
    assert "n_samples" in proc.stderr and "found 'chain_samples'" in proc.stderr
