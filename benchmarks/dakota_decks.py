"""Dakota decks shared by the Dakota benchmarks and the tests that run real Dakota: one text
of each, so a benchmark and a test can never compare against two different problems.

The analytic decks call :data:`DRIVER` (a Python script, ``a``, ``b`` -> ``y1 = a + b / 2``,
``y2 = 4 a - b``, ``y3 = a^2 + b``) through an interface block put in at ``{interface}``; the
benchmarks prepend :data:`PRECISION`. A test imports this module with ``benchmarks/`` on
``sys.path`` (the benchmarks run with it there already)::

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from dakota_decks import MV_DECK  # noqa: E402
"""

from __future__ import annotations

__all__ = ["DRIVER", "PRECISION", "MV_DECK", "PCE_DECK", "VBD_DECK", "BAYES_DECK",
           "BAYES_DATA", "CUU_DECK", "CUU_TARGETS", "ISHIGAMI_PCE_DECK", "vbd_deck",
           "bayes_deck"]

#: The analytic decks' analysis driver: ``python driver.py params.in results.out``.
DRIVER = """\
import sys
lines = [ln.split() for ln in open(sys.argv[1]).read().splitlines()]
n = int(lines[0][0])
v = {ln[1]: float(ln[0]) for ln in lines[1:n + 1]}
m = int(lines[n + 1][0])
# the active set: only the values asked for (Dakota labels the responses of a deck with
# calibration data 'y1_1', ...)
labels = [ln[1].split(":", 1)[1].split("_")[0] for ln in lines[n + 2:n + 2 + m]
          if int(ln[0]) & 1]
a, b = v["a"], v.get("b", 0.0)
y = {"y1": a + 0.5 * b, "y2": 4.0 * a - b, "y3": a * a + b}
open(sys.argv[2], "w").write("".join(f"{y[k]:.17e} {k}\\n" for k in labels))
"""

#: An environment block asking Dakota for full precision (prepended by the benchmarks).
PRECISION = """environment
  output_precision = 16
"""

#: Mean value (local_reliability) of y1, y2 with a, b normal: std = |gradient| * sigma.
MV_DECK = """\
method
  local_reliability
variables
  normal_uncertain = 2
    means = 2.0 1.0
    std_deviations = 0.3 0.2
    descriptors = 'a' 'b'
{interface}responses
  response_functions = 2
    descriptors = 'y1' 'y2'
  numerical_gradients
    method_source dakota
    interval_type central
    fd_step_size = 1e-6
  no_hessians
"""

#: Quadrature PCE of order 3 of y3 = a^2 + b (exact for a quadratic).
PCE_DECK = """\
method
  polynomial_chaos
    quadrature_order = 3
    variance_based_decomp
variables
  normal_uncertain = 1
    means = 2.0
    std_deviations = 0.3
    descriptors = 'a'
  uniform_uncertain = 1
    lower_bounds = 0.0
    upper_bounds = 2.0
    descriptors = 'b'
{interface}responses
  response_functions = 1
    descriptors = 'y3'
  no_gradients
  no_hessians
"""

_VBD_DECK = """\
method
  sampling
    sample_type lhs
    samples = @SAMPLES@
    seed = 7
    variance_based_decomp
variables
  uniform_uncertain = 1
    lower_bounds = 1.0
    upper_bounds = 3.0
    descriptors = 'a'
  normal_uncertain = 1
    means = 1.0
    std_deviations = 0.5
    descriptors = 'b'
{interface}responses
  response_functions = 1
    descriptors = 'y1'
  no_gradients
  no_hessians
"""

_BAYES_DECK = """\
method
  bayes_calibration queso
    chain_samples = @SAMPLES@
    seed = 11
    emulator
      gaussian_process surfpack
      build_samples = 20
    dram
    proposal_covariance prior
    burn_in_samples = 500
variables
  uniform_uncertain = 1
    lower_bounds = 1.0
    upper_bounds = 3.0
    descriptors = 'a'
  continuous_state = 1
    initial_state = 1.0
    descriptors = 'b'
{interface}responses
  calibration_terms = 1
    descriptors = 'y1'
  calibration_data_file = 'data.dat'
    freeform
    num_experiments = 3
    variance_type = 'scalar'
  no_gradients
  no_hessians
"""

#: ``data.dat`` of the Bayes deck: three observations of y1 with noise variance 0.01.
BAYES_DATA = "2.49 0.01\n2.52 0.01\n2.46 0.01\n"


def vbd_deck(n_samples: int) -> str:
    """Variance-based decomposition of y1 on an LHS of ``n_samples`` points (seed 7)."""
    return _VBD_DECK.replace("@SAMPLES@", str(int(n_samples)))


def bayes_deck(chain_samples: int) -> str:
    """DRAM on a 20-point GP emulator, ``chain_samples`` draws (seed 11), on
    :data:`BAYES_DATA`."""
    return _BAYES_DECK.replace("@SAMPLES@", str(int(chain_samples)))


#: The test suite's sizes of the sampled decks (the benchmark runs larger ones).
VBD_DECK = vbd_deck(100)
BAYES_DECK = bayes_deck(3000)

#: Nested calibration under uncertainty: the outer nl2sol fits the std of a to the targets of
#: the inner mean value's std of y1 and y2 (``targets.dat``: :data:`CUU_TARGETS`).
CUU_DECK = """\
environment
  top_method_pointer = 'OUTER'
  output_precision = 16
method
  id_method = 'OUTER'
  nl2sol
    convergence_tolerance = 1e-10
  model_pointer = 'NESTED'
model
  id_model = 'NESTED'
  nested
    sub_method_pointer = 'INNER'
    primary_variable_mapping = 'a'
    secondary_variable_mapping = 'std_deviation'
    primary_response_mapping = 0 1 0 0
                               0 0 0 1
  variables_pointer = 'OV'
  responses_pointer = 'OR'
variables
  id_variables = 'OV'
  continuous_design = 1
    initial_point 0.3
    lower_bounds 0.001
    descriptors 's_a'
responses
  id_responses = 'OR'
  calibration_terms = 2
    descriptors 't1' 't2'
  calibration_data_file = 'targets.dat' freeform num_experiments = 1
  numerical_gradients
    method_source dakota interval_type forward fd_step_size = 1e-7
  no_hessians
method
  id_method = 'INNER'
  local_reliability
  model_pointer = 'INNER_M'
model
  id_model = 'INNER_M'
  single
    interface_pointer = 'I'
  variables_pointer = 'IV'
  responses_pointer = 'IR'
variables
  id_variables = 'IV'
  normal_uncertain = 1
    means = 2.0
    std_deviations = 0.3
    descriptors = 'a'
  continuous_state = 1
    initial_state = 1.0
    descriptors = 'b'
{interface}responses
  id_responses = 'IR'
  response_functions = 2
    descriptors = 'y1' 'y2'
  numerical_gradients
    method_source dakota interval_type central fd_step_size = 1e-6
  no_hessians
"""

#: ``targets.dat`` of the nested CUU deck: target stds of y1 and y2.
CUU_TARGETS = "0.1 1.0\n"

#: Polynomial chaos of Dakota's built-in Ishigami (a = 7, b = 0.1; it maps x in [0, 1] to
#: -pi + 2 pi x: the moments and Sobol' indices of rotoruq's Ishigami on [-pi, pi]^3); the
#: expansion's lines go in at ``{method}`` (``    quadrature_order = 5``, ...).
ISHIGAMI_PCE_DECK = """method
  polynomial_chaos
{method}
    variance_based_decomp
variables
  uniform_uncertain = 3
    lower_bounds = 0 0 0
    upper_bounds = 1 1 1
    descriptors 'x1' 'x2' 'x3'
interface
  direct
    analysis_driver = 'sobol_ishigami'
responses
  response_functions = 1
  no_gradients
  no_hessians
"""
