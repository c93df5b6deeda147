"""The documentation keeps itself true: doctests run, generated numbers match their sources,
the API page lists the public API, and scripts/ and benchmarks/ lint and run.

- Every docstring example (``>>>``) in ``src/rotoruq`` runs as a doctest, one test per module.
- Every public function of the modules listed in ``WITH_EXAMPLES`` has an Examples section.
- Every ``<!-- generated: COMMAND -->`` block of the docs equals what COMMAND prints now (the
  commands print saved JSON results: fast and deterministic); after a new measurement,
  ``python docs/_ext/generated_blocks.py`` rewrites the blocks.
- The API reference (``docs/_ext/public_api.py``, one page per task group) lists every public
  name once, under its public name, and never a private module; each public constant has a
  documentation comment.
- (slow) ``ruff`` passes on scripts/, benchmarks/, examples/ and the docs' extensions, and each
  script or benchmark with a ``--quick`` option runs with it.
- (slow) The site builds with warnings as errors into a temporary folder and writes nothing
  into the source tree, and no public docstring is shown as raw text
  (``docs/_ext/plain_docstrings.py``) but those of files that test_docstrings.py allows.
"""

from __future__ import annotations

import doctest
import importlib
import inspect
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest

import rotoruq

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs" / "_ext"))

import generated_blocks  # noqa: E402
import public_api  # noqa: E402


def _modules_with_examples() -> list[str]:
    found = []
    for info in pkgutil.walk_packages(rotoruq.__path__, "rotoruq."):
        spec = importlib.util.find_spec(info.name)
        if spec and spec.origin and ">>>" in Path(spec.origin).read_text(encoding="utf-8"):
            found.append(info.name)
    return sorted(found)


@pytest.mark.parametrize("module", _modules_with_examples())
def test_docstring_examples_run(module):
    mod = importlib.import_module(module)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    out: list[str] = []
    tests = doctest.DocTestFinder().find(mod, module)
    assert any(t.examples for t in tests), f"{module} has '>>>' but no doctest was found"
    for test in tests:
        runner.run(test, out=out.append)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, "".join(out)


# modules whose public functions all carry an Examples section (with units and shapes)
WITH_EXAMPLES = ["rotoruq.model", "rotoruq.params.space", "rotoruq.params.pairing",
                 "rotoruq.params.catalog", "rotoruq.params.nataf", "rotoruq.methods.sampling",
                 "rotoruq.methods.sensitivity", "rotoruq.methods.pce",
                 "rotoruq.methods.least_squares", "rotoruq.methods.cuu",
                 "rotoruq.rotor.presets", "rotoruq.rotor.airfoil", "rotoruq.rotor.c81",
                 "rotoruq.evaluation.templates", "rotoruq.evaluation.dakota_files"]


def _public_names() -> set[str]:
    names = set(rotoruq.__all__)
    for sub in public_api.SUBPACKAGES:
        names |= set(importlib.import_module(sub).__all__)
    return names


def _public_functions(module: str):
    """Functions defined in ``module`` that the public API (the API page's names) exports."""
    public = _public_names()
    for name, obj in vars(importlib.import_module(module)).items():
        if inspect.isfunction(obj) and obj.__module__ == module and name in public:
            yield name, obj


@pytest.mark.parametrize("module", WITH_EXAMPLES)
def test_public_functions_have_examples(module):
    assert list(_public_functions(module)), f"{module} exports no public function"
    missing = [name for name, obj in _public_functions(module)
               if "Examples\n--------" not in (inspect.getdoc(obj) or "")]
    assert not missing, f"{module}: public functions without an Examples section: {missing}"


BLOCKS = generated_blocks.blocks()


def test_docs_have_generated_blocks():
    pages = {b.page.name for b in BLOCKS}
    assert "benchmarks.md" in pages and len(BLOCKS) >= 10, pages


@pytest.mark.parametrize("block", BLOCKS,
                         ids=[f"{b.page.name}:{b.command.split()[1]}" for b in BLOCKS])
def test_generated_block_is_current(block):
    assert block.text == generated_blocks.run_command(block.command), (
        f"{block.page.relative_to(ROOT)}: the block of '{block.command}' differs from what the "
        f"command prints now; run 'python docs/_ext/generated_blocks.py' to rewrite it")


def test_generated_block_command_must_be_a_script():
    with pytest.raises(ValueError, match="python SCRIPT.py"):
        generated_blocks.run_command("echo 42")
    with pytest.raises(FileNotFoundError, match="no script"):
        generated_blocks.run_command("python benchmarks/no_such_benchmark.py --summary x.json")


def _grouped() -> list[str]:
    return [name for group in public_api.GROUPS.values() for name in group.names]


def test_api_groups_list_every_public_name_once():
    listed = _grouped()
    twice = sorted({n for n in listed if listed.count(n) > 1})
    assert not twice, f"in two groups of docs/_ext/public_api.py GROUPS: {twice}"
    top = set(rotoruq._PUBLIC)
    expected = top | {f"{sub}.{n}" for sub in public_api.SUBPACKAGES
                      for n in importlib.import_module(sub).__all__ if n not in top}
    missing = sorted(expected - set(listed))
    assert not missing, f"public names in no group of docs/_ext/public_api.py GROUPS: {missing}"
    assert set(listed) <= expected, sorted(set(listed) - expected)


def test_api_pages_never_name_a_private_module():
    for key in public_api.GROUPS:
        for name in public_api.GROUPS[key].names:
            assert not any(p.startswith("_") for p in public_api.full_name(name).split(".")), name
            assert public_api.resolve(name) is not None
        page = public_api.group_page(key)
        assert "rotoruq._" not in page, key
    assert "as_generator" in public_api.GROUPS["parameters"].names  # defined in rotoruq._rng
    assert "rotoruq._" not in public_api.index_page()


def test_every_api_group_has_its_page():
    pages = {p.stem for p in (ROOT / "docs" / "api").glob("*.rst")} - {"index"}
    assert pages == set(public_api.GROUPS), (pages, set(public_api.GROUPS))
    for key in public_api.GROUPS:
        text = (ROOT / "docs" / "api" / f"{key}.rst").read_text(encoding="utf-8")
        assert f".. rotoruq-api:: {key}\n" in text, key


def test_public_constants_are_documented():
    constants = [n for n in _grouped() if not callable(public_api.resolve(n))
                 and not inspect.ismodule(public_api.resolve(n))]
    assert "RESPONSES" in constants
    for module in public_api.MODULES.values():
        mod = importlib.import_module(module)
        constants += [f"{module}.{n}" for n in mod.__all__ if n not in rotoruq.__all__
                      and not callable(getattr(mod, n))]
    undocumented = [n for n in constants if not public_api.data_doc(n)]
    assert not undocumented, f"constants without a '#:' comment or docstring: {undocumented}"


def test_tutorials_are_in_the_site():
    index = (ROOT / "docs" / "index.md").read_text(encoding="utf-8")
    for page in sorted((ROOT / "docs" / "tutorials").glob("*.md")):
        assert f"tutorials/{page.stem}\n" in index, f"{page.name} is not in docs/index.md"


LINTED = ["scripts", "benchmarks", "examples", "docs/_ext", "docs/conf.py"]


# benchmarks/reproduce_time.py --quick is `rotoruq reproduce --quick` plus two report redraws
# (7 min on a loaded 2-core machine); tests/test_install.py already runs that reproduction from
# a wheel, and the benchmark's --summary runs in test_generated_block_is_current.
# run in quick mode by their own tests, which also check what they print.
# reproduce_cpu.py and terminal_lines.py --quick are `rotoruq reproduce --quick` again (each
# chapter in a process of its own, or through a pipe); thread_determinism.py's runs are
# tests/test_thread_determinism.py's (its --quick is a study option, not a flag of its own).
# compile_time.py has no --quick: each of its runs is a whole study compiled from an empty
# numba cache (about a minute of CPU per study); reproduce_cold.py --quick is `rotoruq
# reproduce --quick` on an empty numba cache (every kernel compiled: minutes on 2 cores).
# figure_cpu.py has no --quick of its own: it runs `rotoruq reproduce all --quick` for the
# results it redraws, then alternates the redraws (tests/test_report_imports.py checks the
# import claim it measures; its --summary runs in test_generated_block_is_current).
# scripts/mbdyn_verification.py --quick (9 MBDyn runs, 30 CPU-s) is run by
# tests/test_mbdyn_verification.py, which checks its JSON and that it prints.
NOT_SMOKE_RUN = {"reproduce_time.py", "aero_center_calibration.py", "reproduce_cpu.py",
                 "terminal_lines.py", "thread_determinism.py", "compile_time.py",
                 "reproduce_cold.py", "figure_cpu.py", "mbdyn_verification.py"}


# smoke-run only with pytest --extended: minutes of MBDyn runs even at --quick
# (forward_flight_study.py --quick: the study's --quick, its multi-fidelity steps' elastic
# MBDyn runs included)
EXTENDED_SMOKE = {"multifidelity_mbdyn_repeat.py", "forward_flight_study.py"}


def _quick_scripts() -> list:
    return [pytest.param(p, marks=pytest.mark.extended) if p.name in EXTENDED_SMOKE else p
            for p in sorted(p for d in ("scripts", "benchmarks") for p in (ROOT / d).glob("*.py")
                            if '"--quick"' in p.read_text(encoding="utf-8")
                            and p.name not in NOT_SMOKE_RUN)]


@pytest.mark.slow
def test_scripts_and_benchmarks_lint():
    done = subprocess.run([sys.executable, "-m", "ruff", "check", *LINTED], cwd=ROOT,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr


@pytest.mark.slow
@pytest.mark.parametrize("script", _quick_scripts(), ids=lambda p: f"{p.parent.name}/{p.name}")
def test_script_runs_quick(script, tmp_path):
    # from an empty folder: a script must not write into the repository
    done = subprocess.run([sys.executable, str(script), "--quick"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-4000:]
    assert done.stdout.strip(), f"{script.name} --quick printed nothing"


# shown as written (not valid reST) until src/rotoruq/results.py and src/rotoruq/steps/ are
# fixed (tests/test_docstrings.py ALLOWED)
PLAIN_ALLOWED = {"rotoruq.StepResult", "rotoruq.steps.StepContext", "rotoruq.steps.StepType"}


def _source_tree() -> dict[str, tuple[int, int]]:
    """path -> (size, mtime_ns) of every file under docs/ but the build folder and caches."""
    out = {}
    for path in sorted((ROOT / "docs").rglob("*")):
        rel = path.relative_to(ROOT)
        if path.is_file() and not {"_build", "__pycache__"} & set(rel.parts):
            stat = path.stat()
            out[str(rel)] = (stat.st_size, stat.st_mtime_ns)
    return out


@pytest.mark.slow
def test_docs_build_writes_only_into_its_build_folder(tmp_path):
    pytest.importorskip("sphinx", reason="the docs extra is not installed")
    pytest.importorskip("myst_parser", reason="the docs extra is not installed")
    pytest.importorskip("numpydoc", reason="the docs extra is not installed")
    git = ["git", "-C", str(ROOT), "status", "--porcelain", "--untracked-files=all"]
    status = subprocess.run(git, capture_output=True, text=True)
    before = _source_tree()
    done = subprocess.run([sys.executable, "-m", "sphinx", "-W", "-b", "html", "docs",
                           str(tmp_path / "html"), "-d", str(tmp_path / "doctrees")],
                          cwd=ROOT, capture_output=True, text=True, timeout=1200)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-6000:]
    assert (tmp_path / "html" / "api" / "calibration.html").is_file()
    after = _source_tree()
    changed = sorted(k for k in before.keys() | after.keys() if before.get(k) != after.get(k))
    assert not changed, f"the docs build wrote into the source tree: {changed}"
    if status.returncode == 0:  # a git checkout (not an unpacked sdist)
        assert subprocess.run(git, capture_output=True, text=True).stdout == status.stdout
    shown = set()
    for line in (done.stdout + done.stderr).splitlines():
        if "docstrings shown as written" in line:
            shown |= {n.strip() for n in line.partition("):")[2].split(",")}
    assert shown <= PLAIN_ALLOWED, f"docstrings shown as raw text: {sorted(shown - PLAIN_ALLOWED)}"
