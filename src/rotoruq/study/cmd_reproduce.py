"""``rotoruq reproduce [validation|experiment|heldout|all]``: run the bundled reference study
(the thesis's chapters 3 and 4, then the held-out ground-effect validation) and write
``<out>/report/index.html``."""

from __future__ import annotations

import argparse
import json
import logging
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

from ..errors import InputFileError
from ..reference.studies import CHAPTERS, START_ORDER
from .workers import worker_context

HELP = ("reproduce the reference study (thesis chapters 3 and 4, and a held-out validation of "
        "the ground effect) and write the report")

__all__ = ["CHAPTERS", "reproduce", "studies_dir"]


#: The modules a chapter's worker imports, for its steps (numpy, scipy.stats and .optimize,
#: numba with the rotor's and the chains' kernels) and for the figures drawn ahead
#: (matplotlib): about 2 CPU-s of imports (benchmarks/import_time.py, ``chapter_workers``),
#: paid once by the pool's fork server instead of once per worker
#: (:func:`rotoruq.study.workers.worker_context`). Every worker of a run of all the chapters
#: runs at least one chapter and draws figures, so it needs each of them; what a chapter
#: imports beyond them costs ~0.1 s. h5netcdf (optional) writes the chains' netCDF export.
CHAPTER_MODULES = (
    "rotoruq.study.runner",
    "rotoruq.methods.sampling",
    "rotoruq.methods.mcmc.bayes",
    "rotoruq.methods.mcmc.discrepancy",
    "rotoruq.methods.mcmc.sbc",
    "rotoruq.methods.cuu",
    "rotoruq.rotor.model",
    "rotoruq.study.cmd_report",
    "rotoruq.report.html",
    "rotoruq.reference.report",
    "rotoruq.reference.claims",
    "matplotlib.figure",
    "h5netcdf",
)


def studies_dir() -> Path:
    """The study files shipped with the package (``rotoruq/studies/``)."""
    path = Path(__file__).resolve().parents[1] / "studies"
    if not (path / "validation.toml").is_file():
        raise InputFileError(path, None, "the bundled study files (validation.toml, ...)",
                             "an incomplete installation of rotoruq")
    return path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("which", nargs="?", default="all",
                        choices=[*CHAPTERS, "all"],
                        help="chapter 3 (validation), chapter 4 (experiment), the held-out "
                        "ground-effect validation beyond the thesis (heldout) or all three")
    parser.add_argument("--quick", action="store_true",
                        help="small samples: a check that runs in about a minute")
    parser.add_argument("--out", default="rotoruq-results", help="output folder")
    parser.add_argument("--json", action="store_true",
                        help="print the report's path and the seconds per chapter as JSON "
                        "instead of the summary")
    parser.add_argument("--jobs", type=int, default=None,
                        help="chapters run at once, each in its own process (default: one "
                        "per core, at most one per chapter); the numbers are the same at any "
                        "count")


def reproduce(which: str = "all", out: str | Path = "rotoruq-results",
              quick: bool = False, jobs: int | None = None) -> dict:
    """Run the chapters, write the report; returns ``{"report": path, "seconds": {...},
    "runs": {chapter: StudyRun}}``. Holds ``out`` (and so each chapter's folder in it) for the
    whole run.

    The chapters are independent studies (each its own folder, store and seed): with
    ``jobs`` > 1 (default: the machine's cores, at most the chapters asked for) they run at
    once in worker processes, the longest first (:data:`~rotoruq.reference.studies.
    START_ORDER`), and give the same results, bit for bit, as one after the other.
    As each chapter ends, its figures are drawn into the report's figure cache in the same
    pool, while the other chapters run (:func:`rotoruq.report.html.prerender_figures`): the
    report written at the end takes them from there and draws nothing new (the same bytes
    as ``rotoruq report`` of these folders writes).

    ``seconds`` holds each chapter's own time and ``"wall"``, the time until the last
    chapter ended; ``"figures:<chapter>"`` and ``"figures_cpu:<chapter>"``, the wall and
    CPU seconds of drawing its figures ahead; ``"figures_after_chapters"``, the wait for
    the figures after the last chapter ended; ``"report"`` and ``"report_cpu"``, the wall
    and CPU seconds (its figure workers included) of writing the report.
    """
    from .lock import results_lock

    out = Path(out)
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1):
        raise ValueError(f"jobs must be an integer >= 1, got {jobs!r}")
    with results_lock(out, "reproduce"):
        return _reproduce(which, out, quick, jobs)


def start_order(names: list[str]) -> list[str]:
    """The chapters ``names`` in the order several processes start them: the longest first
    (:data:`~rotoruq.reference.studies.START_ORDER`), any other after them as given.

    Examples
    --------
    >>> start_order(["validation", "experiment", "heldout"])
    ['experiment', 'heldout', 'validation']
    """
    return sorted(names, key=lambda n: START_ORDER.index(n) if n in START_ORDER
                  else len(START_ORDER))


def _chapter(name: str, out: Path, quick: bool) -> tuple[Any, float]:
    from .runner import run_study

    t0 = time.perf_counter()
    run = run_study(studies_dir() / CHAPTERS[name], out=out / name, quick=quick)
    return run, time.perf_counter() - t0


def _chain_kernels_cached() -> bool:
    """Whether numba's cache holds the chain kernels (their compiled driver's entry)."""
    from .._compile import is_cached
    from ..methods.mcmc import _kernels

    return is_cached(_kernels.advance) and is_cached(_kernels.run_block_emulator)


def _compile_chain_kernels() -> float:
    """Compile the chain kernels (into numba's cache) by running two tiny calibrations, one
    on an emulator and one on a model, as the chapters' Bayes steps do; its CPU seconds.
    The numbers are thrown away: the chapters load the compiled kernels from the cache."""
    import numpy as np

    from ..methods.mcmc import ChainOptions, EmulatorOptions, NoiseModel, calibrate_bayes
    from ..methods.surrogate import GaussianProcess
    from ..model import FunctionModel
    from ..params import ParameterSpace, Uniform

    c0 = time.process_time()
    model = FunctionModel(lambda x: x[:, :1] * 2.0, ["a"], ["y"])
    prior = ParameterSpace({"a": Uniform(0.0, 1.0)})
    for emulator in (EmulatorOptions(GaussianProcess(), n_emulator_samples=8), None):
        calibrate_bayes(model, np.array([[1.0]]), prior, noise=NoiseModel(noise_std=0.1),
                        chains=ChainOptions(n_samples=50, burn_in=0), emulator=emulator,
                        seed=0)
    return time.process_time() - c0


def _console_level() -> int | None:
    """The level of the progress lines this process prints (None: it prints none)."""
    from .console import printing_level

    return printing_level()


def _child_logging(level: int | None) -> None:
    """A chapter's worker prints its progress lines as this process does."""
    if level is not None:
        from .console import configure_logging

        configure_logging()
        logging.getLogger("rotoruq").setLevel(level)


def _prerender(name: str, out: Path, part: tuple[int, int]) -> tuple[float, float]:
    """Draw a finished chapter's figures (its ``part``) into the report's figure cache (with
    the application ``rotoruq report`` gives them); its seconds, wall and CPU."""
    from .cmd_report import prerender

    t0, c0 = time.perf_counter(), time.process_time()
    prerender(out / name, out / "report", part)
    return time.perf_counter() - t0, time.process_time() - c0


def _cpu() -> float:
    """CPU seconds of this process and of its children that have ended."""
    import resource

    own, ended = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(
        resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + ended.ru_utime + ended.ru_stime


def _reproduce(which: str, out: Path, quick: bool, jobs: int | None) -> dict:
    from ..results import is_study_dir
    from .cmd_report import write

    names = list(CHAPTERS) if which == "all" else [which]
    jobs = min(jobs or os.cpu_count() or 1, len(names))
    seconds: dict[str, float] = {}
    runs: dict[str, Any] = {}
    t0 = time.perf_counter()
    if jobs == 1:
        for name in names:
            runs[name], seconds[name] = _chapter(name, out, quick)
    else:
        # not forked from this process: a fork would copy its threads' locks (BLAS, numba);
        # forked by a fork server that imported the chapters' modules once (issue 34)
        with worker_context(CHAPTER_MODULES) as ctx, ProcessPoolExecutor(
                jobs, mp_context=ctx, initializer=_child_logging,
                initargs=(_console_level(),)) as pool:
            # on an empty numba cache, one worker compiles the chain kernels while the first
            # chapter compiles the rotor's (the chapters then load both from the cache; a
            # family is compiled by one process at a time: rotoruq._compile.compile_lock)
            warm = None if _chain_kernels_cached() else pool.submit(_compile_chain_kernels)
            # the pool starts the tasks in the order they were submitted
            futures = {name: pool.submit(_chapter, name, out, quick)
                       for name in start_order(names)}
            # as each chapter ends, its figures are queued behind the chapters not yet
            # started: they fill a core the chapters leave idle, and the report written at
            # the end takes them from its figure cache (same bytes: the cache key covers the
            # results and the drawing code); split in one part per process, so that the
            # last chapter's figures do not wait on one core while the other is idle
            chapter_of = {fut: name for name, fut in futures.items()}
            drawing = {chapter_of[fut]: [pool.submit(_prerender, chapter_of[fut], out,
                                                     (k, jobs)) for k in range(jobs)]
                       for fut in as_completed(futures.values()) if fut.exception() is None}
            seconds["wall"] = time.perf_counter() - t0
            if warm is not None:
                try:
                    seconds["compile_chain_kernels_cpu"] = warm.result()
                except Exception as exc:  # noqa: BLE001 - the chapters compiled them
                    logging.getLogger(__name__).warning(
                        "the chain kernels were not compiled ahead (%s: %s); the chapters "
                        "compiled them", type(exc).__name__, exc)
            for name in names:  # in order: the first failure raised is the first chapter's
                runs[name], seconds[name] = futures[name].result()
            t0 = time.perf_counter()
            for name in names:
                try:
                    parts = [f.result() for f in drawing[name]]
                    seconds[f"figures:{name}"] = max(w for w, _ in parts)
                    seconds[f"figures_cpu:{name}"] = sum(c for _, c in parts)
                except Exception as exc:  # noqa: BLE001 - the report draws them itself
                    logging.getLogger(__name__).warning(
                        "report: the figures of %s were not drawn ahead (%s: %s); the report "
                        "draws them", name, type(exc).__name__, exc)
            # the figures still being drawn when the last chapter ended
            seconds["figures_after_chapters"] = time.perf_counter() - t0
    if "wall" not in seconds:
        seconds["wall"] = time.perf_counter() - t0
    t0, c0 = time.perf_counter(), _cpu()
    index = write([out / n for n in CHAPTERS if is_study_dir(out / n)], out / "report")
    seconds["report"] = time.perf_counter() - t0
    seconds["report_cpu"] = _cpu() - c0  # with the figure workers it started
    return {"report": str(index), "seconds": seconds, "runs": runs}


def run(args: argparse.Namespace) -> int:
    from .cmd_run import EXIT_FAILED_EVALUATIONS, exit_status, summary, verdict

    result = reproduce(args.which, args.out, args.quick, args.jobs)
    if args.json:
        print(json.dumps({"report": result["report"], "seconds": result["seconds"]}, indent=1))
    elif not getattr(args, "quiet", False):
        for res in result["runs"].values():
            print(summary(res))
        print(verdict(*result["runs"].values()))
        for res in result["runs"].values():
            print(f"results: {res.out}")
        print(f"report: {result['report']}")  # last: what the user opens next
    codes = [exit_status(res, "reproduce") for res in result["runs"].values()]
    return EXIT_FAILED_EVALUATIONS if any(codes) else 0
