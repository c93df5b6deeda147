"""Dakota input decks in and out: a reader of Dakota's deck grammar, a translator of the deck
features a rotorcraft UQ study uses into a study file's TOML text, and an exporter that writes
a study's steps back as Dakota decks whose ``fork`` interface runs the study's model through
``rotoruq driver``.

The grammar read: blocks ``environment``, ``method``, ``model``, ``variables``, ``interface``,
``responses``; inside a block, keywords (unquoted words) each followed by their values
(numbers or quoted strings); ``=`` between a keyword and its values is optional; ``#`` starts a
comment. Every keyword the translator does not translate raises
:class:`~rotoruq.errors.InputFileError` naming the deck, the line and what it translates there.

Translated (see :func:`deck_to_study`):

* variables: ``normal``, ``lognormal``, ``uniform``, ``loguniform``, ``triangular``,
  ``exponential``, ``beta``, ``gamma``, ``gumbel``, ``weibull`` and
  ``continuous_interval_uncertain`` with their Dakota parameters and ``descriptors``;
  ``continuous_state`` -> fixed inputs; ``continuous_design`` -> the calibrated inputs of a
  least-squares step, fixed inputs elsewhere.
* responses: ``response_functions`` / ``calibration_terms`` with ``descriptors``, gradients
  (``no_``/``numerical_``/``analytic_gradients``, the model's own choice in rotoruq),
  ``calibration_data_file`` (inline ``[data]`` columns, ``variance_type 'scalar'`` -> the noise
  std of each response).
* methods: ``sampling`` (``lhs``/``random``, ``samples``, ``seed``; with
  ``variance_based_decomp`` a ``sensitivity`` step), ``local_reliability`` (a ``mean_value``
  step; with ``mpp_search`` a ``reliability`` step, ``integration first_order|second_order``,
  RIA ``response_levels``, PMA ``probability_levels``), ``polynomial_chaos``
  (``quadrature_order q`` -> order q - 1 by quadrature, ``expansion_order`` with
  ``collocation_points``/``collocation_ratio`` -> regression), ``global_evidence``,
  ``nl2sol`` (a ``least_squares`` step), ``bayes_calibration queso`` (``mh``/``dr``/``am``/
  ``dram``, ``emulator gaussian_process``, ``build_samples``, ``chain_samples``,
  ``burn_in_samples``, ``proposal_covariance prior|derivatives``), and the nested model of
  the thesis's CUU (outer ``nl2sol`` on ``continuous_design`` variables mapped to the
  ``std_deviation`` / ``mean`` of inner uncertain variables, inner ``local_reliability``,
  ``sampling`` or ``polynomial_chaos``, targets from the outer calibration data) -> a ``cuu``
  step with ``weighting = "absolute"`` (Dakota's residuals are plain differences).
* interface: ``fork``/``system`` with ``analysis_drivers``; a ``rotoruq driver`` string gives
  ``[model] preset`` (``--preset``), ``fixed`` (``--set``), renamed variables and responses
  (``--map``); any other driver an external model ``command``. File handling keywords
  (``parameters_file``, ``file_tag``, ``work_directory`` ...) concern Dakota's own runs and
  are read and left out.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import shlex
import sys
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputFileError

__all__ = ["DeckEntry", "DeckBlock", "Deck", "DeckProblems", "DeckTranslation", "parse_deck",
           "read_deck", "deck_to_study", "translate_deck", "OUTPUT_ONLY",
           "study_to_decks", "EXPORTABLE"]

BLOCKS = ("environment", "method", "model", "variables", "interface", "responses")
# Dakota's aliases (and its older method names) of the keywords read here -> the name used
# below. Variable attributes also take the group's prefix (``nuv_means``, ``lnuv_zetas``...).
ALIASES = {"descriptor": "descriptors", "analysis_driver": "analysis_drivers",
           "num_response_functions": "response_functions",
           "least_squares_terms": "calibration_terms",
           "num_least_squares_terms": "calibration_terms",
           "num_calibration_terms": "calibration_terms",
           "least_squares_data_file": "calibration_data_file",
           "interval_probs": "interval_probabilities",
           "iuv_interval_probs": "interval_probabilities",
           "range_probabilities": "interval_probabilities",
           "range_probs": "interval_probabilities",
           "interval_uncertain": "continuous_interval_uncertain",
           "secondary_variable_mappings": "secondary_variable_mapping",
           "response_descriptors": "descriptors",
           "experiment_variance_type": "variance_type",
           "least_squares_weights": "weights", "calibration_weights": "weights",
           "asynch": "asynchronous",
           "fd_gradient_step_size": "fd_step_size",
           "tabular_graphics_data": "tabular_data", "tabular_graphics_file": "tabular_data_file",
           "method_pointer": "top_method_pointer",
           "nond_sampling": "sampling", "nond_local_reliability": "local_reliability",
           "nond_polynomial_chaos": "polynomial_chaos",
           "nond_global_evidence": "global_evidence",
           "nond_bayes_calibration": "bayes_calibration",
           "initial_samples": "samples", "kriging": "gaussian_process",
           "huv_bin_abscissas": "abscissas", "huv_bin_counts": "counts",
           "huv_bin_ordinates": "ordinates", "huv_bin_descriptors": "descriptors",
           "num_pairs": "pairs_per_variable",
           "iuv_num_intervals": "num_intervals"}
for _prefix, _attrs in {
        "nuv": ("means", "std_deviations", "lower_bounds", "upper_bounds", "descriptors"),
        "lnuv": ("means", "std_deviations", "lambdas", "zetas", "error_factors",
                 "lower_bounds", "upper_bounds", "descriptors"),
        "uuv": ("lower_bounds", "upper_bounds", "descriptors"),
        "luuv": ("lower_bounds", "upper_bounds", "descriptors"),
        "tuv": ("modes", "lower_bounds", "upper_bounds", "descriptors"),
        "euv": ("betas", "descriptors"),
        "buv": ("alphas", "betas", "lower_bounds", "upper_bounds", "descriptors"),
        "gauv": ("alphas", "betas", "descriptors"), "guuv": ("alphas", "betas", "descriptors"),
        "fuv": ("alphas", "betas", "descriptors"), "wuv": ("alphas", "betas", "descriptors"),
        "iuv": ("descriptors",),
        "cdv": ("initial_point", "lower_bounds", "upper_bounds", "descriptors"),
        "csv": ("initial_state", "lower_bounds", "upper_bounds", "descriptors")}.items():
    ALIASES.update({f"{_prefix}_{a}": a for a in _attrs})
_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eEdD][+-]?\d+)?$")
_REPEAT = re.compile(r"^(\d+)\*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eEdD][+-]?\d+)?)$")
_STAR = re.compile(r"(?<![\w.])(\d+)\s*\*\s*(?=[+-]?[\d.])")
_TOKEN = re.compile(r"""'[^']*'|"[^"]*"|=|[^\s=,'"]+""")  # commas separate, as blanks


@dataclass(frozen=True)
class DeckEntry:
    """One keyword of a deck and its values (floats, or strings for quoted values); ``line``
    is 1-based."""

    keyword: str
    values: tuple
    line: int


@dataclass(frozen=True, eq=False)
class DeckBlock:
    """A top-level block (``method``, ``variables`` ...) and its entries in deck order."""

    kind: str
    entries: tuple[DeckEntry, ...]
    line: int

    def find(self, keyword: str) -> DeckEntry | None:
        """The first entry ``keyword`` (None when absent)."""
        return next((e for e in self.entries if e.keyword == keyword), None)

    @property
    def id(self) -> str | None:
        e = self.find(f"id_{self.kind}")
        return str(e.values[0]) if e and e.values else None


@dataclass(frozen=True, eq=False)
class Deck:
    """A parsed Dakota input deck: its blocks in order and the file it came from."""

    blocks: tuple[DeckBlock, ...]
    path: str = "<deck>"

    def of(self, kind: str) -> list[DeckBlock]:
        return [b for b in self.blocks if b.kind == kind]


def _value(tok: str) -> Any:
    if tok[0] in "'\"":
        return tok[1:-1]
    return float(tok.replace("d", "e").replace("D", "e"))


def parse_deck(text: str, path: str | os.PathLike = "<deck>") -> Deck:
    """Parse a Dakota input deck's text into blocks of keyword entries.

    Parameters
    ----------
    text : the deck.
    path : the deck's name in error messages.

    Returns
    -------
    Deck

    Examples
    --------
    >>> d = parse_deck("method\\n  sampling  # LHS\\n    samples = 10 seed 3\\n")
    >>> [(e.keyword, e.values, e.line) for e in d.blocks[0].entries]
    [('sampling', (), 2), ('samples', (10.0,), 3), ('seed', (3.0,), 3)]
    """
    path = str(path)
    blocks: list[DeckBlock] = []
    kind, start, entries = None, 0, []  # type: ignore[var-annotated]
    for no, raw in enumerate(text.splitlines(), 1):
        line = _strip_comment(raw)
        # N * value with blanks around the star (outside quotes): one N*value token
        parts = re.split(r"""('[^']*'|"[^"]*")""", line)
        line = "".join(s if i % 2 else _STAR.sub(r"\1*", s) for i, s in enumerate(parts))
        toks = _TOKEN.findall(line)
        if line.count("'") % 2 or line.count('"') % 2:
            raise InputFileError(path, no, "a closed quoted string", raw.strip())
        for tok in toks:
            if tok == "=":
                continue
            rep = _REPEAT.match(tok)
            if tok[0] in "'\"" or _NUMBER.match(tok) or rep:
                if not entries:
                    raise InputFileError(path, no, "a keyword before a value", tok)
                last = entries[-1]
                # Dakota's N*value: the value N times
                vals = (_value(rep[2]),) * int(rep[1]) if rep else (_value(tok),)
                entries[-1] = DeckEntry(last.keyword, last.values + vals, last.line)
                continue
            word = tok.lower()
            if word in BLOCKS:
                if kind is not None:
                    blocks.append(DeckBlock(kind, tuple(entries), start))
                kind, start, entries = word, no, []
                continue
            if kind is None:
                raise InputFileError(path, no, "a block keyword first (" + ", ".join(BLOCKS)
                                     + ")", tok)
            entries.append(DeckEntry(ALIASES.get(word, word), (), no))
    if kind is not None:
        blocks.append(DeckBlock(kind, tuple(entries), start))
    return Deck(tuple(blocks), path)


def _strip_comment(line: str) -> str:
    quote = None
    for i, ch in enumerate(line):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch == "#":
            return line[:i]
    return line


def read_deck(path: str | os.PathLike) -> Deck:
    """:func:`parse_deck` of a deck file."""
    return parse_deck(Path(path).read_text(), path)


# --------------------------------------------------------------------------- import
#: Keywords that only shape Dakota's own output, restart file, bookkeeping or scheduling:
#: accepted where Dakota accepts them and listed in one note (a rotoruq run keeps its own
#: store, report and executor), or that ask Dakota for an extra statistic rotoruq does not
#: compute (named as such in the note). Nothing here changes a number the study computes.
OUTPUT_ONLY: dict[str, frozenset[str]] = {
    "environment": frozenset((
        "tabular_data", "tabular_data_file", "annotated", "custom_annotated", "freeform",
        "header", "eval_id", "interface_id", "output_precision", "results_output",
        "results_output_file", "hdf5", "text", "model_selection", "interface_selection",
        "graphics", "check", "output_file", "error_file", "read_restart", "write_restart",
        "stop_restart", "pre_run", "run", "post_run", "input", "output", "utype",
        "augment_utype", "none", "all", "top_method_pointer", "interfaces", "solution",
        "models", "surrogate")),
    "method": frozenset((
        "output", "silent", "quiet", "normal", "verbose", "debug", "final_moments",
        "standard", "central", "none", "speculative", "id_method", "model_pointer",
        "std_regression_coeffs", "tolerance_intervals", "coverage", "confidence_level",
        "posterior_stats", "kl_divergence", "mutual_info", "export_chain_points_file",
        "export_expansion_file", "export_approx_points_file")),
    "interface": frozenset((
        "id_interface", "fork", "system", "direct", "parameters_file", "results_file",
        "file_tag", "file_save", "work_directory", "named", "directory_tag", "directory_save",
        "link_files", "copy_files", "replace", "verbatim", "labeled", "allow_existing_results",
        "asynchronous", "evaluation_concurrency", "analysis_concurrency",
        "local_evaluation_scheduling", "dedicated", "static", "dynamic",
        "evaluation_scheduling", "evaluation_servers", "analysis_servers",
        "analysis_scheduling", "processors_per_evaluation", "processors_per_analysis",
        "deactivate", "active_set_vector", "evaluation_cache", "restart_file",
        "strict_cache_equality", "cache_tolerance", "peer", "master", "batch", "size",
        "input_filter", "output_filter")),
    "responses": frozenset(("id_responses", "method_source", "dakota",
                            "vendor", "interval_type", "forward", "central",
                            "fd_step_size", "absolute", "bounds", "relative")),
    "variables": frozenset(("id_variables",)),
    "model": frozenset(("id_model", "single", "variables_pointer", "interface_pointer",
                        "responses_pointer")),
}

#: What an ignored keyword is, for the note (keywords not listed: "Dakota's output").
_IGNORED_WHAT = {"evaluation_concurrency": "Dakota's scheduling",
                 "asynchronous": "Dakota's scheduling", "batch": "Dakota's scheduling",
                 "deactivate": "Dakota's cache and restart", "restart_file": "Dakota's restart",
                 "read_restart": "Dakota's restart", "write_restart": "Dakota's restart",
                 "fork": "the interface kind", "system": "the interface kind",
                 "direct": "the interface kind", "work_directory": "Dakota's file handling",
                 "file_tag": "Dakota's file handling", "file_save": "Dakota's file handling",
                 "parameters_file": "Dakota's file handling",
                 "results_file": "Dakota's file handling",
                 "id_method": "block ids", "id_model": "block ids", "id_variables": "block ids",
                 "id_interface": "block ids", "id_responses": "block ids",
                 "model_pointer": "block ids", "top_method_pointer": "block ids",
                 "variables_pointer": "block ids", "interface_pointer": "block ids",
                 "responses_pointer": "block ids", "single": "the model kind",
                 **dict.fromkeys(("std_regression_coeffs", "tolerance_intervals", "coverage",
                                  "confidence_level", "posterior_stats", "kl_divergence",
                                  "mutual_info"),
                                 "statistics Dakota would add that rotoruq does not compute "
                                 "(the step's own results stand without them)"),
                 **dict.fromkeys(("method_source", "dakota", "vendor", "interval_type",
                                  "forward", "central", "fd_step_size"),
                                 "Dakota's finite-difference settings (rotoruq takes the "
                                 "model's analytic gradient, else its own central "
                                 "differences)")}


class DeckProblems(InputFileError):
    """Every problem of a Dakota deck at once: ``problems`` holds one
    :class:`~rotoruq.errors.InputFileError` per problem (file, line, what was expected and
    found); the message lists them in line order. With one problem the message is that
    problem's own."""

    def __init__(self, path: str, problems: Sequence[InputFileError]):
        self.problems = sorted(problems, key=lambda p: (p.line or 0))
        first = self.problems[0]
        super().__init__(first.path, first.line, first.expected, first.found)
        if len(self.problems) > 1:
            lines = [f"{path}: {len(self.problems)} problems, each with its line:"]
            for p in self.problems:
                msg = str(p)
                lines.append("  " + (msg[len(p.path) + 2:] if msg.startswith(p.path) else msg))
            self.args = ("\n".join(lines),)

    def __str__(self) -> str:
        return str(self.args[0])


class _Tx:
    """A translation's problems and ignored keywords, collected over the whole deck."""

    def __init__(self, deck: Deck):
        self.deck = deck
        self.problems: list[InputFileError] = []
        self.ignored: list[DeckEntry] = []
        self.notes: list[str] = []

    def problem(self, line: int | None, expected: str, found: str | None = None) -> None:
        self.problems.append(InputFileError(self.deck.path, line, expected, found))

    def guard(self, fn: Any, *args: Any, default: Any = None) -> Any:
        """``fn(*args)``; a problem it raises is recorded and ``default`` returned."""
        try:
            return fn(*args)
        except DeckProblems as exc:
            self.problems.extend(exc.problems)
        except InputFileError as exc:
            self.problems.append(exc)
        return default

    def done(self) -> None:
        if self.problems:
            seen, unique = set(), []
            for p in self.problems:
                key = (p.line, p.expected, p.found)
                if key not in seen:
                    seen.add(key)
                    unique.append(p)
            raise DeckProblems(self.deck.path, unique)

    def ignored_note(self) -> str:
        """One line per kind of ignored keyword, with the deck lines."""
        groups: dict[str, list[str]] = {}
        for e in self.ignored:
            what = _IGNORED_WHAT.get(e.keyword, "Dakota's output")
            if what in ("block ids", "the interface kind", "the model kind"):
                continue
            groups.setdefault(what, []).append(f"{e.keyword} (line {e.line})")
        return "; ".join(f"{what}: {', '.join(dict.fromkeys(v))}" for what, v in groups.items())


class _Cursor:
    """Walks a block's entries; every entry must be taken by the translator. An unknown
    keyword is recorded as a problem (or, when it only shapes Dakota's own output, as
    ignored) and the walk goes on, so a deck's problems are all reported at once."""

    def __init__(self, deck: Deck, block: DeckBlock, what: str, tx: _Tx | None = None):
        self.deck, self.block, self.what = deck, block, what
        self.tx = tx if tx is not None else _Tx(deck)
        self.i = 0

    def __iter__(self) -> Iterator[DeckEntry]:
        while self.i < len(self.block.entries):
            e = self.block.entries[self.i]
            self.i += 1
            yield e

    def peek(self) -> DeckEntry | None:
        return self.block.entries[self.i] if self.i < len(self.block.entries) else None

    def next_if(self, *keywords: str) -> DeckEntry | None:
        e = self.peek()
        if e is not None and e.keyword in keywords:
            self.i += 1
            return e
        return None

    def fail(self, e: DeckEntry, expected: str) -> Any:
        raise InputFileError(self.deck.path, e.line, expected, e.keyword)

    def unknown(self, e: DeckEntry, known: Sequence[str]) -> None:
        if e.keyword in OUTPUT_ONLY.get(self.block.kind, ()):
            self.tx.ignored.append(e)
            return
        listed = [k for k in known if k not in OUTPUT_ONLY.get(self.block.kind, ())]
        self.tx.problem(e.line, (f"a {self.what} keyword rotoruq translates ("
                                 + ", ".join(listed) + ")" if listed else
                                 f"a {self.what} keyword rotoruq reads (those that shape "
                                 "Dakota's own output)") + f"; '{e.keyword}' is not translated",
                        e.keyword)


def _num(c: _Cursor, e: DeckEntry, n: int | None = 1, kind: str = "number") -> list:
    vals = list(e.values)
    if any(not isinstance(v, float) for v in vals) or (n is not None and len(vals) != n) \
            or not vals:
        c.fail(e, f"{n if n is not None else 'one or more'} {kind}(s) after '{e.keyword}'")
    if kind == "integer" and any(v != int(v) for v in vals):
        c.fail(e, f"integers after '{e.keyword}'")
    return [int(v) for v in vals] if kind == "integer" else vals


def _strs(c: _Cursor, e: DeckEntry, n: int | None = None) -> list[str]:
    vals = list(e.values)
    if any(not isinstance(v, str) for v in vals) or (n is not None and len(vals) != n) \
            or not vals:
        c.fail(e, f"{n if n is not None else 'one or more'} quoted string(s) after "
               f"'{e.keyword}'")
    return vals


# variables: group keyword -> (default descriptor prefix, its attributes), in Dakota's own
# order of variable types (the order of its correlation matrix and of a parameter study's
# points: design, aleatory uncertain by type, epistemic, state)
_GROUPS: dict[str, tuple[str, tuple[str, ...]]] = {
    "continuous_design": ("cdv", ("initial_point", "lower_bounds", "upper_bounds",
                                  "scale_types", "scales")),
    "normal_uncertain": ("nuv", ("means", "std_deviations", "lower_bounds", "upper_bounds",
                                 "initial_point")),
    "lognormal_uncertain": ("lnuv", ("parameters", "option_1", "option_2", "option_3",
                                     "means", "std_deviations", "lambdas", "zetas",
                                     "error_factors", "lower_bounds", "upper_bounds",
                                     "initial_point")),
    "uniform_uncertain": ("uuv", ("lower_bounds", "upper_bounds", "initial_point")),
    "loguniform_uncertain": ("luuv", ("lower_bounds", "upper_bounds", "initial_point")),
    "triangular_uncertain": ("tuv", ("modes", "lower_bounds", "upper_bounds",
                                     "initial_point")),
    "exponential_uncertain": ("euv", ("betas", "initial_point")),
    "beta_uncertain": ("buv", ("alphas", "betas", "lower_bounds", "upper_bounds",
                               "initial_point")),
    "gamma_uncertain": ("gauv", ("alphas", "betas", "initial_point")),
    "gumbel_uncertain": ("guuv", ("alphas", "betas", "initial_point")),
    "frechet_uncertain": ("fuv", ("alphas", "betas", "initial_point")),
    "weibull_uncertain": ("wuv", ("alphas", "betas", "initial_point")),
    "histogram_bin_uncertain": ("hbuv", ("pairs_per_variable", "abscissas", "counts",
                                         "ordinates", "initial_point")),
    "continuous_interval_uncertain": ("ciuv", ("num_intervals", "interval_probabilities",
                                               "lower_bounds", "upper_bounds",
                                               "initial_point")),
    "continuous_state": ("csv", ("initial_state", "lower_bounds", "upper_bounds")),
}
#: the aleatory uncertain types, in Dakota's order (its correlation matrix's order)
_ALEATORY = tuple(g for g in _GROUPS if g.endswith("_uncertain")
                  and g != "continuous_interval_uncertain")
# attributes whose values are split over the variables by a count (histograms, intervals)
_SPLIT = {"pairs_per_variable": ("abscissas", "counts", "ordinates"),
          "num_intervals": ("interval_probabilities", "lower_bounds", "upper_bounds")}


def _is_group(keyword: str) -> bool:
    """A keyword that opens a group of variables in Dakota's grammar (translated or not)."""
    return (keyword in _GROUPS or keyword.endswith(("_uncertain", "_uncertain_set"))
            or keyword.startswith(("continuous_", "discrete_")))


@dataclass
class _Var:
    name: str
    group: str
    attrs: dict
    line: int


@dataclass
class _Vars:
    uncertain: list[_Var] = field(default_factory=list)
    state: list[_Var] = field(default_factory=list)
    design: list[_Var] = field(default_factory=list)
    correlation: tuple[list[float], int] | None = None  # (values, line)
    active: DeckEntry | None = None


def _read_variables(deck: Deck, block: DeckBlock, tx: _Tx | None = None) -> _Vars:
    c = _Cursor(deck, block, "variables", tx)
    out = _Vars()
    for e in c:
        if e.keyword in ("id_variables", "mixed", "relaxed"):
            continue
        if e.keyword == "uncertain_correlation_matrix":
            out.correlation = (_num(c, e, None), e.line)
            continue
        if e.keyword == "active":
            a = c.next_if("all", "design", "uncertain", "aleatory", "epistemic", "state")
            out.active = a if a is not None and a.keyword in ("all", "design", "state") \
                else None
            continue
        if e.keyword not in _GROUPS:
            c.unknown(e, ["id_variables", *_GROUPS, "uncertain_correlation_matrix", "active"])
            if _is_group(e.keyword):  # its attributes go with it, not listed again
                while (a := c.peek()) is not None and not _is_group(a.keyword) \
                        and a.keyword not in ("uncertain_correlation_matrix", "active"):
                    c.i += 1
            continue
        c.tx.guard(_read_group, c, e, out)
    return out


def _read_group(c: _Cursor, e: DeckEntry, out: _Vars) -> None:
    n = _num(c, e, 1, "integer")[0]
    prefix, attrs = _GROUPS[e.keyword]
    got: dict[str, list] = {}
    names = [f"{prefix}_{i + 1}" for i in range(n)]
    while (a := c.next_if("descriptors", *attrs)) is not None:
        if a.keyword == "descriptors":
            names = _strs(c, a, n)
        elif a.keyword in ("parameters", "option_1", "option_2", "option_3"):
            continue  # Dakota 6.24's lognormal form choice: the keywords that follow say it
        elif a.keyword in _SPLIT:
            got[a.keyword] = _num(c, a, n, "integer")
        else:
            got[a.keyword] = _num(c, a, None)
    target = (out.state if e.keyword == "continuous_state" else
              out.design if e.keyword == "continuous_design" else out.uncertain)
    split = next((s for s in _SPLIT if e.keyword.startswith(
        "histogram" if s == "pairs_per_variable" else "continuous_interval")), None)
    if split is not None:
        counts = got.get(split)
        if counts is None:
            first = next((got[k] for k in _SPLIT[split] if k in got), [])
            if len(first) % n:
                c.fail(e, f"{split} for {n} variables whose values do not split evenly")
            counts = [len(first) // n] * n if split == "pairs_per_variable" else [1] * n
        per: dict[str, list[list[float]]] = {}
        for k in _SPLIT[split]:
            if k in got:
                if len(got[k]) != sum(counts):
                    c.fail(e, f"{sum(counts)} values of {k} ({split} in all)")
                bounds = np.cumsum([0, *counts])
                per[k] = [got[k][bounds[i]:bounds[i + 1]] for i in range(n)]
        for i, name in enumerate(names):
            attrs_i = {k: v[i] for k, v in per.items()}
            if "initial_point" in got:
                attrs_i["initial_point"] = got["initial_point"][i]
            target.append(_Var(name, e.keyword, attrs_i, e.line))
        return
    for k, v in got.items():
        if len(v) != n:
            c.fail(e, f"{n} values of {k} (one per variable)")
    for i, name in enumerate(names):
        target.append(_Var(name, e.keyword, {k: v[i] for k, v in got.items()}, e.line))


def _distribution(v: _Var, deck: Deck) -> dict:
    a, g = v.attrs, v.group

    def need(*keys: str) -> list:
        miss = [k for k in keys if k not in a]
        if miss:
            raise InputFileError(deck.path, v.line, f"{', '.join(miss)} for {g} {v.name!r}")
        return [a[k] for k in keys]

    if g == "normal_uncertain":
        mean, std = need("means", "std_deviations")
        lo, hi = a.get("lower_bounds", -math.inf), a.get("upper_bounds", math.inf)
        if math.isinf(lo) and math.isinf(hi):
            return {"distribution": "normal", "mean": mean, "std": std}
        return {"distribution": "truncated_normal", "mean": mean, "std": std,
                "lower": lo, "upper": hi}
    if g == "lognormal_uncertain":
        if "lambdas" in a or "zetas" in a:
            lam, zeta = need("lambdas", "zetas")
            out = {"distribution": "lognormal", "lambda": lam, "zeta": zeta}
        elif "error_factors" in a:
            mean, ef = need("means", "error_factors")
            out = {"distribution": "lognormal", "mean": mean, "error_factor": ef}
        else:
            mean, std = need("means", "std_deviations")
            out = {"distribution": "lognormal", "mean": mean, "std": std}
        lo, hi = a.get("lower_bounds", 0.0), a.get("upper_bounds", math.inf)
        if lo > 0.0 or not math.isinf(hi):
            out.update(lower=lo, upper=hi)
        return out
    if g in ("uniform_uncertain", "loguniform_uncertain"):
        lo, hi = need("lower_bounds", "upper_bounds")
        return {"distribution": g.split("_")[0], "lower": lo, "upper": hi}
    if g == "triangular_uncertain":
        mode, lo, hi = need("modes", "lower_bounds", "upper_bounds")
        return {"distribution": "triangular", "mode": mode, "lower": lo, "upper": hi}
    if g == "exponential_uncertain":
        return {"distribution": "exponential", "beta": need("betas")[0]}
    if g == "beta_uncertain":
        al, be, lo, hi = need("alphas", "betas", "lower_bounds", "upper_bounds")
        return {"distribution": "beta", "alpha": al, "beta": be, "lower": lo, "upper": hi}
    if g == "histogram_bin_uncertain":
        x = need("abscissas")[0]
        if "counts" in a:
            counts = list(a["counts"])
        else:
            y = need("ordinates")[0]
            if len(y) != len(x):
                raise InputFileError(deck.path, v.line, f"as many ordinates as abscissas for "
                                     f"{v.name!r}")
            # a density height per bin -> the bin's mass (Dakota normalises both forms)
            counts = [y[i] * (x[i + 1] - x[i]) for i in range(len(x) - 1)] + [0.0]
        if len(counts) != len(x):
            raise InputFileError(deck.path, v.line, f"as many counts as abscissas for "
                                 f"{v.name!r} (the last count is 0)")
        return {"distribution": "histogram_bin", "abscissas": list(x), "counts": counts}
    if g == "continuous_interval_uncertain":
        # the evidence step takes the cells; the parameter is their hull
        lo, hi = need("lower_bounds", "upper_bounds")
        return {"distribution": "uniform", "lower": min(lo), "upper": max(hi)}
    al, be = need("alphas", "betas")
    return {"distribution": g.split("_")[0], "alpha": al, "beta": be}


def _design_distribution(v: _Var, deck: Deck) -> tuple[dict, float | None]:
    """A calibrated design variable: the uniform distribution on its bounds (the support the
    least-squares step searches) and its initial point, when it is not the midpoint (the
    step's ``start``)."""
    a = v.attrs
    lo, hi = a.get("lower_bounds", -math.inf), a.get("upper_bounds", math.inf)
    x0 = a.get("initial_point")
    if math.isinf(lo) or math.isinf(hi):
        if x0 is None:
            raise InputFileError(deck.path, v.line, f"initial_point or both bounds for "
                                 f"continuous_design {v.name!r}")
        return {"distribution": "normal", "mean": x0, "std": abs(x0) * 0.1 or 1.0}, None
    if x0 is not None and not lo <= x0 <= hi:
        raise InputFileError(deck.path, v.line, f"an initial_point of {v.name!r} within its "
                             f"bounds [{lo!r}, {hi!r}]", repr(x0))
    if x0 is None or math.isclose(x0, 0.5 * (lo + hi), rel_tol=1e-12, abs_tol=1e-300):
        x0 = None
    return {"distribution": "uniform", "lower": lo, "upper": hi}, x0


@dataclass
class _Responses:
    names: list[str]
    kind: str
    data: dict | None = None
    noise_std: dict | None = None
    line: int = 0
    gradients: str = "none"  # none | numerical | analytic
    weights: list[float] | None = None


_RESP_KEYS = ("response_functions", "calibration_terms", "descriptors", "calibration_data_file",
              "no_gradients", "numerical_gradients", "analytic_gradients", "no_hessians",
              "weights",
              "scalar_responses", "scalar_calibration_terms")
_DATA_KEYS = ("freeform", "annotated", "custom_annotated", "header", "eval_id", "interface_id",
              "num_experiments", "variance_type", "num_config_variables")


def _read_responses(deck: Deck, block: DeckBlock, tx: _Tx | None = None) -> _Responses:
    c = _Cursor(deck, block, "responses", tx)
    out = _Responses([], "", line=block.line)
    descriptors: DeckEntry | None = None
    data: tuple[DeckEntry, str, list[DeckEntry]] | None = None
    for e in c:
        if e.keyword in ("response_functions", "calibration_terms"):
            n = _num(c, e, 1, "integer")[0]
            out.kind = e.keyword
            prefix = "response_fn" if e.keyword == "response_functions" else "least_sq_term"
            out.names = [f"{prefix}_{i + 1}" for i in range(n)]
        elif e.keyword in ("scalar_responses", "scalar_calibration_terms"):
            if out.kind and _num(c, e, 1, "integer")[0] != len(out.names):
                c.fail(e, f"{len(out.names)} scalar responses (field responses are not "
                       "translated)")
        elif e.keyword == "descriptors":
            descriptors = e
        elif e.keyword == "calibration_data_file":
            opts = []
            while (a := c.next_if(*_DATA_KEYS)) is not None:
                opts.append(a)
            data = (e, _strs(c, e, 1)[0], opts)
        elif e.keyword == "no_hessians":
            continue  # as rotoruq: no Hessian is asked for
        elif e.keyword in ("no_gradients", "numerical_gradients", "analytic_gradients"):
            out.gradients = e.keyword.split("_")[0]
        elif e.keyword == "weights":
            out.weights = _num(c, e, None)
        else:
            c.unknown(e, _RESP_KEYS)
    if not out.names:
        raise InputFileError(deck.path, block.line, "response_functions = N or "
                             "calibration_terms = N in the responses block")
    if descriptors is not None:
        out.names = _strs(c, descriptors, len(out.names))
    if out.weights is not None and len(out.weights) != len(out.names):
        raise InputFileError(deck.path, block.line, f"{len(out.names)} weights (one per "
                             "calibration term)")
    if data is not None:
        e, fname, opts = data
        layout, n_exp, variance = "annotated", 1, ["none"]
        for a in opts:
            if a.keyword in ("freeform", "annotated", "custom_annotated"):
                layout = a.keyword
            elif a.keyword == "num_experiments":
                n_exp = _num(c, a, 1, "integer")[0]
            elif a.keyword == "variance_type":
                variance = _strs(c, a)
                if any(v not in ("none", "scalar") for v in variance) \
                        or len(variance) not in (1, len(out.names)):
                    c.fail(a, "variance_type 'none' or 'scalar', once or per response "
                           "(one noise std per response)")
            elif a.keyword == "num_config_variables" and _num(c, a, 1, "integer")[0]:
                c.fail(a, "num_config_variables 0 (configuration variables are not "
                       "translated: give them as a [data] column and a sweep)")
        if len(variance) == 1:
            variance = variance * len(out.names)
        out.data, out.noise_std = _calibration_data(c, e, fname, layout, n_exp, variance,
                                                    out.names)
    return out


def _calibration_data(c: _Cursor, e: DeckEntry, fname: str, layout: str, n_exp: int,
                      variance: list[str], names: list[str]) -> tuple[dict, dict | None]:
    """Read a calibration data file as Dakota does: a freeform file is a stream of numbers
    (any number per line), n_exp experiments of the responses' values, then a variance per
    response whose variance_type is 'scalar'; an annotated file has a header line and
    ``eval_id`` (and, with custom_annotated, what its options say) before each row."""
    path = Path(c.deck.path).parent / fname
    if not path.is_file():
        c.fail(e, f"an existing calibration data file ({path})")
    text = [ln for ln in path.read_text().splitlines()
            if ln.strip() and not ln.lstrip().startswith("#")]
    m = len(names)
    n_var = sum(v == "scalar" for v in variance)
    width = m + n_var
    if layout == "freeform":
        toks = " ".join(text).split()
    else:
        rows = [ln.split() for ln in text[1:]]  # the header line
        toks = [tok for r in rows[:n_exp] for tok in r[-width:]]
    try:
        flat = [float(v) for v in toks]
    except ValueError:
        c.fail(e, f"numbers in {fname}")
    if len(flat) < n_exp * width:
        c.fail(e, f"{n_exp} experiments of {width} numbers in {fname} ({layout}; found "
               f"{len(flat)} numbers)")
    vals = np.array(flat[:n_exp * width]).reshape(n_exp, width)
    data = {r: [float(v) for v in vals[:, j]] for j, r in enumerate(names)}
    noise = None
    if n_var:
        k = m
        noise = {}
        for j, r in enumerate(names):
            if variance[j] == "scalar":
                noise[r] = float(np.sqrt(np.mean(vals[:, k])))
                k += 1
    return data, noise


@dataclass
class _Driver:
    preset: str | None = None
    command: list[str] | None = None
    function: str | None = None
    components: list[str] = field(default_factory=list)
    fixed: dict = field(default_factory=dict)
    mapping: dict = field(default_factory=dict)
    outputs: list[str] = field(default_factory=list)
    parameters_format: str = "standard"
    failure: dict = field(default_factory=dict)
    gradients: str | None = None


_IF_KEYS = ("analysis_drivers", "analysis_components", "aprepro", "failure_capture", "fork",
            "system", "direct")


def _dakota_functions() -> Mapping[str, Any]:
    """Dakota's built-in test functions rotoruq has (name -> info)."""
    try:
        from ..testfunctions import FUNCTIONS
    except ImportError:  # pragma: no cover - the module ships with rotoruq
        return {}
    return FUNCTIONS


def _read_interface(deck: Deck, block: DeckBlock, tx: _Tx | None = None) -> _Driver:
    c = _Cursor(deck, block, "interface", tx)
    drv = _Driver()
    seen = None
    kind = "fork"
    for e in c:
        if e.keyword in ("fork", "system", "direct"):
            kind = e.keyword
            c.tx.ignored.append(e)
        elif e.keyword == "analysis_drivers":
            strs = _strs(c, e)
            if len(strs) != 1:
                c.fail(e, "one analysis driver (several drivers per evaluation are not "
                       "translated)")
            seen = (strs[0], e)
        elif e.keyword == "aprepro":
            drv.parameters_format = "aprepro"
        elif e.keyword == "analysis_components":
            drv.components = _strs(c, e)
        elif e.keyword == "failure_capture":
            a = c.next_if("abort", "recover", "retry", "continuation")
            if a is None or a.keyword == "continuation":
                c.fail(e, "failure_capture abort, recover VALUES or retry N")
            assert a is not None
            drv.failure = ({"failure": "abort"} if a.keyword == "abort" else
                           {"failure": "recover", "recover": _num(c, a, None)}
                           if a.keyword == "recover" else
                           {"failure": "retry", "retries": _num(c, a, 1, "integer")[0]})
        elif e.keyword in ("python", "matlab", "scilab", "plugin", "grid"):
            c.fail(e, "a fork, system or direct interface (Dakota's " + e.keyword
                   + " interface runs code inside Dakota)")
        else:
            c.unknown(e, _IF_KEYS)
    if seen is None:
        raise InputFileError(deck.path, block.line, "analysis_drivers = '...' in the "
                             "interface block")
    text, e = seen
    functions = _dakota_functions()
    if kind == "direct":
        if text not in functions:
            c.fail(e, "one of Dakota's test functions rotoruq has for a direct interface ("
                   + ", ".join(sorted(functions)) + f"); '{text}' is not one")
        drv.function = text
        return drv
    if drv.components:
        c.fail(e, "analysis_components only with one of Dakota's test functions (a fork or "
               "system driver reads its own options)")
    argv = shlex.split(text)
    if len(argv) == 1 and argv[0] in functions and not _program_exists(deck, argv[0]):
        # Dakota's test suite runs its test functions as programs of the same name
        drv.function = argv[0]
        c.tx.notes.append(f"the {kind} driver '{argv[0]}' (line {e.line}) is not a program "
                          "here: Dakota's test function of that name, built in")
        return drv
    _parse_driver(c, e, text, drv)
    return drv


def _program_exists(deck: Deck, name: str) -> bool:
    import shutil

    return (Path(deck.path).parent / name).exists() or shutil.which(name) is not None


def _parse_driver(c: _Cursor, e: DeckEntry, text: str, drv: _Driver) -> None:
    argv = shlex.split(text)
    rest: list[str] | None = None
    if argv and Path(argv[0]).name.startswith("rotoruq") and argv[1:2] == ["driver"]:
        rest = argv[2:]
    elif len(argv) >= 4 and argv[1:3] == ["-m", "rotoruq.study.cli"] and argv[3] == "driver":
        rest = argv[4:]
    if rest is None:
        drv.command = argv
        return
    p = argparse.ArgumentParser(add_help=False, exit_on_error=False)
    p.add_argument("--preset", default="gvpm")
    p.add_argument("--set", action="append", default=[], dest="fixed")
    p.add_argument("--map", action="append", default=[], dest="mapping")
    p.add_argument("--outputs", "--resp", action="append", default=[], dest="outputs")
    try:
        args, extra = p.parse_known_args(rest)
    except argparse.ArgumentError as exc:
        c.fail(e, f"a rotoruq driver string ({exc})")
    if extra:
        c.fail(e, "rotoruq driver options --preset, --set NAME=VALUE, --map DECK=NAME, "
               f"--outputs; not {' '.join(extra)}")
    from ..evaluation.driver import named_pairs

    drv.preset = args.preset
    try:
        drv.fixed = named_pairs(args.fixed, "--set", number=True)
        drv.mapping = named_pairs(args.mapping, "--map")
    except Exception as exc:  # the driver's own message, at the deck line
        c.fail(e, f"a rotoruq driver string ({exc})")
    drv.outputs = [o for item in args.outputs for o in item.split(",")]


# methods -------------------------------------------------------------------------------
_LEVELS = ("response_levels", "probability_levels", "reliability_levels",
           "gen_reliability_levels")
_LEVEL_KEYS = (*_LEVELS, *(f"num_{k}" for k in _LEVELS), "compute", "probabilities",
               "reliabilities", "gen_reliabilities", "distribution", "cumulative",
               "complementary")
_SAMPLING = ("sample_type", "lhs", "random", "low_discrepancy", "rank_1_lattice",
             "digital_net", "sobol", "samples", "seed", "fixed_seed", "variance_based_decomp",
             *_LEVEL_KEYS)
_RELIABILITY = ("mpp_search", "x_taylor_mean", "u_taylor_mean", "x_taylor_mpp",
                "u_taylor_mpp", "x_two_point", "u_two_point", "no_approx", "integration",
                "first_order", "second_order", *_LEVEL_KEYS)
_PCE = ("quadrature_order", "dimension_preference", "expansion_order", "expansion_samples",
        "collocation_points",
        "collocation_ratio", "seed", "fixed_seed", "variance_based_decomp", "askey",
        "least_squares", "svd", "samples_on_emulator", "samples", "sample_type", "lhs",
        "random", "normalized", "nested", "non_nested", *_LEVEL_KEYS)
_EVIDENCE = ("sample_type", "lhs", "random", "samples", "seed", *_LEVEL_KEYS)
_NL2SOL = ("convergence_tolerance", "max_iterations", "max_function_evaluations")
_BAYES = ("queso", "mh", "metropolis_hastings", "dr", "delayed_rejection", "am",
          "adaptive_metropolis", "dram", "chain_samples", "samples", "burn_in_samples",
          "seed", "emulator", "gaussian_process", "surfpack", "build_samples",
          "proposal_covariance", "prior", "derivatives")
_METHOD_COMMON = ("id_method", "model_pointer")
_METHODS = ("sampling", "local_reliability", "polynomial_chaos", "global_evidence", "nl2sol",
            "bayes_calibration")
#: Dakota's other iterators, named in the message when a deck asks for one
_ALLOWED = {"sampling": _SAMPLING, "local_reliability": _RELIABILITY,
            "polynomial_chaos": _PCE, "global_evidence": _EVIDENCE, "nl2sol": _NL2SOL,
            "bayes_calibration": _BAYES}


@dataclass
class _Method:
    kind: str
    opts: dict
    block: DeckBlock
    seed: int | None = None
    path: str = "<deck>"


def _levels(c: _Cursor, e: DeckEntry, names: list[str], counts: list[int] | None) -> dict:
    vals = _num(c, e, None)
    if counts is None:
        if len(vals) % len(names):
            c.fail(e, f"levels for each of the {len(names)} responses (or num_"
                   f"{e.keyword} per response)")
        counts = [len(vals) // len(names)] * len(names)
    if len(counts) != len(names) or sum(counts) != len(vals):
        c.fail(e, f"{sum(counts)} levels split over {len(names)} responses by num_"
               f"{e.keyword}")
    out, k = {}, 0
    for r, n in zip(names, counts, strict=True):
        if n:
            out[r] = vals[k:k + n]
        k += n
    return out


def _read_method(deck: Deck, block: DeckBlock, responses: list[str],
                 tx: _Tx | None = None) -> _Method:
    c = _Cursor(deck, block, "method", tx)
    # the method's keyword may follow its options (Dakota reads a block in any order)
    head = next((e for e in block.entries if e.keyword in _METHODS), None)
    if head is None:
        other = next((e for e in block.entries if e.keyword not in _METHOD_COMMON
                      and e.keyword not in OUTPUT_ONLY["method"]), None)
        raise InputFileError(deck.path, other.line if other else block.line,
                             "a method rotoruq translates (" + ", ".join(_METHODS) + ")",
                             other.keyword if other else None)
    kind = head.keyword
    c.what = kind
    opts: dict[str, Any] = {}
    seed = None
    levels: dict[str, DeckEntry] = {}
    counts: dict[str, list[int]] = {}
    allowed = _ALLOWED[kind]
    for e in c:
        if e is head or e.keyword in _METHOD_COMMON:
            continue
        if e.keyword not in allowed:
            c.unknown(e, allowed)
            continue
        c.tx.guard(_method_entry, c, e, kind, opts, levels, counts)
        if e.keyword == "seed":
            seed = opts.pop("seed", None)
    if kind == "bayes_calibration" and "queso" not in opts.get("_seen", ()):
        c.tx.problem(head.line, "bayes_calibration queso (the other samplers are not "
                     "translated)", kind)
    opts.pop("_seen", None)
    for k, e in levels.items():
        if len(responses):
            opts[k] = c.tx.guard(_levels, c, e, responses, counts.get(k), default={})
    if kind == "bayes_calibration" and "emulator" in opts and "gaussian_process" not in opts:
        raise InputFileError(deck.path, block.line, "emulator gaussian_process (other "
                             "emulators are not translated)")
    return _Method(kind, opts, block, seed, deck.path)


def _method_entry(c: _Cursor, e: DeckEntry, kind: str, opts: dict, levels: dict,
                  counts: dict) -> None:
    k = e.keyword
    opts.setdefault("_seen", set()).add(k)
    if k == "seed":
        opts["seed"] = _num(c, e, 1, "integer")[0]
    elif k == "samples" and kind == "polynomial_chaos":
        opts["samples_on_emulator"] = _num(c, e, 1, "integer")[0]
    elif k in ("samples", "chain_samples", "build_samples", "burn_in_samples",
               "quadrature_order", "expansion_order", "collocation_points",
               "max_iterations", "max_function_evaluations", "samples_on_emulator"):
        opts[k] = _num(c, e, 1, "integer")[0]
    elif k in ("convergence_tolerance", "collocation_ratio"):
        opts[k] = _num(c, e, 1)[0]
    elif k == "dimension_preference":
        opts["dimension_preference"] = (_num(c, e, None), e.line)
    elif k == "expansion_samples":
        opts["expansion_samples"] = _num(c, e, 1, "integer")[0]
    elif k in _LEVELS:
        levels[k] = e
    elif k.startswith("num_") and k[4:] in _LEVELS:
        counts[k[4:]] = _num(c, e, None, "integer")
    elif k in ("lhs", "random"):
        opts["design"] = k
    elif k in ("low_discrepancy", "rank_1_lattice", "digital_net", "sobol"):
        # Dakota's sequences (a rank-1 lattice by default) are not rotoruq's: a scrambled
        # Sobol' sequence is the same kind of estimator on other points, as LHS is
        opts["design"] = "sobol"
        if k != "sobol":
            c.tx.notes.append(f"sample_type {k} (line {e.line}): rotoruq's scrambled Sobol' "
                              "sequence (a low-discrepancy design on other points than "
                              "Dakota's)")
    elif k in ("mh", "metropolis_hastings", "dr", "delayed_rejection", "am",
               "adaptive_metropolis", "dram"):
        opts["sampler"] = {"metropolis_hastings": "mh", "delayed_rejection": "dr",
                           "adaptive_metropolis": "am"}.get(k, k)
    elif k in ("prior", "derivatives"):
        opts["proposal"] = "prior" if k == "prior" else "hessian"
    elif k in ("mpp_search", "x_taylor_mean", "u_taylor_mean", "x_taylor_mpp",
               "u_taylor_mpp", "x_two_point", "u_two_point", "no_approx"):
        opts["mpp_search"] = True
        if k != "mpp_search":  # the search itself: rotoruq's option of the same name
            opts["approximation"] = "none" if k == "no_approx" else k
    elif k in ("cumulative", "complementary"):
        opts["distribution"] = "cdf" if k == "cumulative" else "ccdf"
    elif k in ("probabilities", "reliabilities", "gen_reliabilities"):
        opts["compute"] = k
    elif k in ("first_order", "second_order", "variance_based_decomp", "gaussian_process",
               "emulator"):
        opts[k] = True


def _level_options(o: dict) -> dict:
    """The level mappings a method block asks for, as step options."""
    out = {k: o[k] for k in _LEVELS if o.get(k)}
    if out or "distribution" in o:
        for k in ("distribution", "compute"):
            if k in o:
                out[k] = o[k]
    return out


def _step(m: _Method, design_params: list[str]) -> dict:
    o = m.opts
    step: dict[str, Any]
    if m.kind == "sampling":
        if o.get("variance_based_decomp"):
            step = {"name": "sensitivity", "type": "sensitivity"}
        else:
            step = {"name": "sampling", "type": "sampling"}
        if "samples" in o:
            step["n_samples"] = o["samples"]
        if "design" in o:
            step["design"] = o["design"]
        if step["type"] == "sampling":
            step.update(_level_options(o))
        elif _level_options(o):
            raise InputFileError(m.path, m.block.line, "no level mappings with "
                                 "variance_based_decomp (the sensitivity step has none)")
        return step
    if m.kind == "local_reliability":
        if o.get("mpp_search"):
            step = {"name": "reliability", "type": "reliability",
                    "integration": "second_order" if o.get("second_order") else "first_order"}
            if "approximation" in o:
                step["approximation"] = o["approximation"]
        else:
            step = {"name": "mean_value", "type": "mean_value"}
        step.update(_level_options(o))
        return step
    if m.kind == "polynomial_chaos":
        step = {"name": "pce", "type": "pce"}
        if "quadrature_order" in o:
            step.update(order=max(o["quadrature_order"] - 1, 1), estimator="quadrature")
        elif "expansion_order" in o and "expansion_samples" in o:
            # coefficients by sampling projection (Dakota's expectation approach)
            step.update(order=o["expansion_order"], estimator="sampling",
                        n_samples=o["expansion_samples"])
        elif "expansion_order" in o:
            step.update(order=o["expansion_order"], estimator="regression")
            if "collocation_points" in o:
                step["n_samples"] = o["collocation_points"]
            elif "collocation_ratio" in o:
                step["n_samples"] = -1  # filled in with the dimension
        else:
            raise InputFileError(m.path, m.block.line,
                                 "quadrature_order or expansion_order for polynomial_chaos")
        levels = _level_options(o)
        numerical = [k for k in ("response_levels", "probability_levels",
                                 "gen_reliability_levels") if levels.get(k) and (
            k != "response_levels" or levels.get("compute") != "reliabilities")]
        if "samples_on_emulator" in o and numerical:  # Dakota draws them for these only
            step["samples_on_expansion"] = o["samples_on_emulator"]
        step.update(levels)
        return step
    if m.kind == "global_evidence":
        step = {"name": "evidence", "type": "evidence"}
        if "samples" in o:
            step["n_samples"] = o["samples"]
        step.update(_level_options(o))
        return step
    if m.kind == "nl2sol":
        step = {"name": "least_squares", "type": "least_squares", "optimizer": "nl2sol"}
        for dk, sk in (("convergence_tolerance", "tolerance"),
                       ("max_iterations", "max_iterations"),
                       ("max_function_evaluations", "max_function_evaluations")):
            if dk in o:
                step[sk] = o[dk]
        if design_params:
            step["parameters"] = design_params
        return step
    step = {"name": "bayes", "type": "bayes_calibration", "data": "calibration",
            "sampler": o.get("sampler", "dram"),
            "emulator": "gp" if o.get("emulator") else "none"}
    burn = o.get("burn_in_samples", 0)
    n = o.get("chain_samples", o.get("samples"))
    if n is not None:
        if n - burn < 10:
            raise InputFileError(m.path, m.block.line, "chain_samples at least 10 more "
                                 "than burn_in_samples")
        step["n_samples"] = n - burn
    step["burn_in"] = burn
    if "build_samples" in o:
        step["n_emulator_samples"] = o["build_samples"]
    if "proposal" in o:
        step["proposal"] = o["proposal"]
    return step


def _pointer(block: DeckBlock, key: str) -> str | None:
    e = block.find(key)
    return str(e.values[0]) if e and e.values else None


def _nested_cuu(deck: Deck) -> tuple[DeckBlock, DeckBlock, DeckBlock, dict] | None:
    """The thesis's CUU form: (outer method, inner method, the nested model block, mapping)."""
    nested = [b for b in deck.of("model") if b.find("nested")]
    if not nested:
        return None
    if len(nested) > 1:
        raise InputFileError(deck.path, nested[1].line, "one nested model (the CUU form)")
    nb = nested[0]
    c = _Cursor(deck, nb, "nested model")  # its own problems: the nested form stops here
    info: dict[str, Any] = {}
    for e in c:
        k = e.keyword
        if k in ("id_model", "nested", "variables_pointer", "responses_pointer"):
            info[k] = e.values[0] if e.values else None
        elif k == "sub_method_pointer":
            info[k] = _strs(c, e, 1)[0]
        elif k == "primary_variable_mapping":
            info[k] = _strs(c, e)
        elif k == "secondary_variable_mapping":
            info["secondary"] = _strs(c, e)
            info["secondary_line"] = e.line
        elif k == "primary_response_mapping":
            info[k] = _num(c, e, None)
        else:
            c.unknown(e, ["sub_method_pointer", "primary_variable_mapping",
                          "secondary_variable_mapping", "primary_response_mapping",
                          "variables_pointer", "responses_pointer", "id_model"])
    c.tx.done()
    methods = deck.of("method")
    inner = [m for m in methods if m.id == info.get("sub_method_pointer")]
    outer = [m for m in methods if _pointer(m, "model_pointer") == nb.id]
    if len(inner) != 1 or len(outer) != 1:
        raise InputFileError(deck.path, nb.line, "one outer method whose model_pointer names "
                             "this nested model and one inner method named by its "
                             "sub_method_pointer")
    return outer[0], inner[0], nb, info


def _by_id(deck: Deck, kind: str, ident: str | None, line: int) -> DeckBlock:
    blocks = deck.of(kind)
    if ident is None:
        if len(blocks) == 1:
            return blocks[0]
        unnamed = [b for b in blocks if b.id is None]
        if len(unnamed) == 1:
            return unnamed[0]
        raise InputFileError(deck.path, line, f"a {kind}s_pointer naming one of the "
                             f"{len(blocks)} {kind} blocks")
    for b in blocks:
        if b.id == ident:
            return b
    raise InputFileError(deck.path, line, f"a {kind} block with id_{kind} = '{ident}'")


def deck_to_study(deck: Deck, *, name: str | None = None) -> str:
    """Translate a parsed Dakota deck into the TOML text of a rotoruq study file.

    Parameters
    ----------
    deck : from :func:`read_deck` (calibration data files are read relative to its path).
    name : the study's name (default: the deck file's stem).

    Returns
    -------
    str : a study file that :func:`rotoruq.study.schema.load_study` accepts.

    Raises
    ------
    InputFileError : naming the deck line of every keyword that is not translated.

    Examples
    --------
    >>> d = parse_deck('''method
    ...   sampling sample_type lhs samples 20 seed 5
    ... variables
    ...   normal_uncertain 1 means 0.108 std_deviations 0.0054 descriptors 'cla_m03'
    ...   continuous_state 1 initial_state 4.0 descriptors 'height_over_radius'
    ... interface
    ...   fork analysis_drivers 'rotoruq driver --preset gvpm --set omega=230'
    ... responses
    ...   response_functions 1 descriptors 'thrust'
    ...   no_gradients no_hessians''', "vbd.in")
    >>> print(deck_to_study(d).split("[[steps]]")[1].strip())
    name = "sampling"
    type = "sampling"
    n_samples = 20
    design = "lhs"
    """
    return translate_deck(deck, name=name).text


@dataclass(frozen=True)
class DeckTranslation:
    """A Dakota deck translated into a study file.

    Attributes
    ----------
    text : str
        The study file's TOML text.
    ignored : str
        The keywords that only shape Dakota's own output (or its scheduling, cache and
        restart), each with its deck line, grouped by what they do; "" when none.
    notes : tuple of str
        Other things a user should know about the translation (a test program taken as the
        built-in function of the same name...).
    """

    text: str
    ignored: str = ""
    notes: tuple[str, ...] = ()


def translate_deck(deck: Deck, *, name: str | None = None) -> DeckTranslation:
    """Translate a parsed Dakota deck; every problem of the deck is reported at once.

    Parameters
    ----------
    deck : from :func:`read_deck`.
    name : the study's name (default: the deck file's stem).

    Returns
    -------
    DeckTranslation

    Raises
    ------
    DeckProblems
        Listing each keyword that is not translated, and each malformed value, with its
        line (an :class:`~rotoruq.errors.InputFileError`).

    Examples
    --------
    >>> d = parse_deck('''environment
    ...   graphics
    ...   tabular_data
    ... method
    ...   sampling samples 20 seed 5
    ...   output verbose
    ... variables
    ...   uniform_uncertain 2 lower_bounds -2 -2 upper_bounds 2 2 descriptors 'x1' 'x2'
    ... interface
    ...   direct analysis_drivers 'rosenbrock'
    ... responses
    ...   response_functions 1 no_gradients no_hessians''', "rosen.in")
    >>> tr = translate_deck(d)
    >>> tr.ignored
    "Dakota's output: graphics (line 2), tabular_data (line 3), output (line 6), verbose (line 6)"
    >>> print(tr.text.split("[model]")[1].split("[parameters")[0].strip())
    function = "rosenbrock"
    responses = ["response_fn_1"]
    """
    tx = _Tx(deck)
    cuu = tx.guard(_nested_cuu, deck)
    if cuu is None and any(b.find("nested") for b in deck.of("model")):
        tx.done()  # the nested form's own problems: nothing else to read
    if cuu is not None:
        text = tx.guard(_cuu_study, deck, cuu, name, tx)
        tx.done()
        return DeckTranslation(text, tx.ignored_note(), tuple(tx.notes))
    methods = deck.of("method")
    method_block: DeckBlock | None = methods[0] if methods else None
    if not methods:
        tx.problem(None, "a method block")
    elif len(methods) > 1:
        top = next((b for b in deck.of("environment")
                    for e in b.entries if e.keyword == "top_method_pointer"), None)
        tx.problem(methods[1].line, "one method block (or the nested CUU form: an outer "
                   "nl2sol on a nested model)" + (" (top_method_pointer names a method that "
                                                  "calls others)" if top else ""))
    for kind in ("variables", "interface", "responses"):
        if len(deck.of(kind)) != 1:
            blocks = deck.of(kind)
            tx.problem(blocks[1].line if len(blocks) > 1 else None, f"one {kind} block")
    for b in deck.of("model"):
        if not b.find("single"):
            kinds = [e.keyword for e in b.entries if e.keyword in (
                "surrogate", "nested", "hierarchical", "random_field", "active_subspace",
                "adapted_basis")]
            tx.problem(b.line, "a single model (or the nested CUU form)",
                       kinds[0] if kinds else None)
        else:
            c = _Cursor(deck, b, "model", tx)
            for e in c:
                c.unknown(e, ["single"])
    _check_environment(deck, tx)

    def one(kind: str) -> DeckBlock | None:
        blocks = deck.of(kind)
        return blocks[0] if blocks else None

    rb, vb, ib = one("responses"), one("variables"), one("interface")
    resp = tx.guard(_read_responses, deck, rb, tx) if rb else None
    method = (tx.guard(_read_method, deck, method_block, resp.names if resp else [], tx)
              if method_block is not None else None)
    variables = tx.guard(_read_variables, deck, vb, tx) if vb else None
    drv = tx.guard(_read_interface, deck, ib, tx) if ib else None
    if None in (resp, method, variables, drv):
        tx.done()
        raise InputFileError(deck.path, None, "a method, variables, interface and responses "
                             "block")  # pragma: no cover - done() raised the reason
    assert resp is not None and method is not None and variables is not None \
        and drv is not None
    text = tx.guard(_single_study, deck, name, resp, method, variables, drv, tx)
    tx.done()
    return DeckTranslation(text, tx.ignored_note(), tuple(tx.notes))


def _single_study(deck: Deck, name: str | None, resp: _Responses, method: _Method,
                  variables: _Vars, drv: _Driver, tx: _Tx) -> str:
    calibrates_design = method.kind == "nl2sol"
    params = list(variables.uncertain)
    fixed = {v.name: v.attrs["initial_state"] for v in variables.state
             if "initial_state" in v.attrs}
    design_params: list[str] = []
    if variables.active is not None and (variables.state or variables.design) \
            and not calibrates_design:
        tx.problem(variables.active.line, "active uncertain (rotoruq holds state and "
                   "design variables fixed in a UQ method)", f"active {variables.active.keyword}")
    for v in variables.design:
        if calibrates_design:
            params.append(v)
            design_params.append(v.name)
        else:
            if "initial_point" not in v.attrs:
                lo, hi = v.attrs.get("lower_bounds"), v.attrs.get("upper_bounds")
                if lo is None or hi is None:
                    tx.problem(v.line, f"initial_point or bounds for {v.name!r} (held fixed "
                               "there)")
                    continue
                # Dakota's default initial point of a bounded design variable: the midpoint
                v.attrs["initial_point"] = 0.5 * (lo + hi) if lo > -1e30 and hi < 1e30 \
                    else (0.0 if lo <= 0.0 <= hi else lo if lo > 0 else hi)
            fixed[v.name] = v.attrs["initial_point"]
    if method.kind == "nl2sol" and variables.uncertain:
        tx.problem(variables.uncertain[0].line, "continuous_design variables only for nl2sol "
                   "(they are the calibrated inputs)")
    for v in variables.state:
        if "initial_state" not in v.attrs:
            lo, hi = v.attrs.get("lower_bounds"), v.attrs.get("upper_bounds")
            if lo is not None and hi is not None:
                fixed[v.name] = 0.5 * (lo + hi)  # Dakota's default initial state
            else:
                fixed[v.name] = 0.0 if not (lo or hi) else (lo if lo is not None else hi)
    if method.kind == "bayes_calibration" and resp.data is None:
        tx.problem(deck.of("responses")[0].line, "calibration_data_file for " + method.kind)
    step = _step(method, design_params)
    if method.kind == "nl2sol":
        if resp.data is not None:
            step["data"] = "calibration"
        if resp.weights is not None:
            step["residual_weights"] = {drv.mapping.get(r, r): w for r, w in zip(
                resp.names, resp.weights, strict=True)}
    if step.get("n_samples") == -1:
        d = len(params)
        step["n_samples"] = math.ceil(method.opts["collocation_ratio"]
                                      * math.comb(method.opts["expansion_order"] + d, d))
    if step["type"] == "evidence":
        step["intervals"] = {}
        for v in params:
            if v.group != "continuous_interval_uncertain":
                continue
            lo, hi = v.attrs["lower_bounds"], v.attrs["upper_bounds"]
            probs = v.attrs.get("interval_probabilities", [1.0 / len(lo)] * len(lo))
            step["intervals"][v.name] = [[a, b, w] for a, b, w in zip(lo, hi, probs,
                                                                      strict=True)]
    elif any(v.group == "continuous_interval_uncertain" for v in params):
        v = next(v for v in params if v.group == "continuous_interval_uncertain")
        tx.problem(v.line, "interval (epistemic) variables only with global_evidence",
                   "continuous_interval_uncertain")
    if "dimension_preference" in method.opts and step["type"] == "pce":
        pref, line = method.opts["dimension_preference"]
        ordered = _dakota_order(params)
        if len(pref) != len(ordered):
            tx.problem(line, f"{len(ordered)} dimension_preference values (one per uncertain "
                       "variable)", f"{len(pref)} values")
        elif "quadrature_order" not in method.opts:
            tx.problem(line, "dimension_preference with quadrature_order (an anisotropic "
                       "expansion order is not translated)", "dimension_preference")
        else:
            step["dimension_preference"] = {v.name: float(x) for v, x in zip(ordered, pref,
                                                                               strict=True)}
    if step["type"] == "bayes_calibration" and resp.noise_std:
        step["noise_std"] = {drv.mapping.get(r, r): s for r, s in resp.noise_std.items()}
    if resp.gradients == "analytic" and drv.command is not None \
            and method.kind in ("local_reliability", "nl2sol"):
        drv.gradients = "analytic"
    tx.done()
    if drv.function is not None:
        # Dakota hands a direct function its variables by type (design, uncertain, state);
        # a study hands it the parameters, then the fixed inputs: the same order when the
        # parameters are written in Dakota's order and the fixed inputs follow them
        params = _dakota_order(params)
        info = _dakota_functions()[drv.function]
        dakota = [v.name for v in _dakota_order(
            [*variables.design, *variables.uncertain, *variables.state])]
        ours = [v.name for v in params] + [n for n in fixed if n not in
                                           {v.name for v in params}]
        if not info.labels and dakota != ours:
            tx.problem(variables.design[0].line if variables.design else None,
                       f"design variables held fixed after the uncertain ones for "
                       f"'{drv.function}' (it takes its variables by position, design "
                       "first in Dakota; rotoruq hands it the parameters first)",
                       " ".join(dakota))
        tx.done()
    return _emit(deck, name, method.seed, drv, resp, params, fixed, [step],
                 design=set(design_params), correlation=variables.correlation)


def _check_environment(deck: Deck, tx: _Tx | None = None) -> None:
    for b in deck.of("environment"):
        c = _Cursor(deck, b, "environment", tx)
        for e in c:
            c.unknown(e, [])


def _cuu_study(deck: Deck, cuu: tuple, name: str | None, tx: _Tx) -> str:
    outer_b, inner_b, nb, info = cuu
    _check_environment(deck, tx)
    outer_vars = _read_variables(deck, _by_id(deck, "variables",
                                              _pointer(outer_b, "variables_pointer")
                                              or info.get("variables_pointer"), nb.line), tx)
    inner_model = _by_id(deck, "model", _pointer(inner_b, "model_pointer"), inner_b.line)
    ic = _Cursor(deck, inner_model, "inner model", tx)
    for e in ic:
        if e.keyword not in ("id_model", "single", "variables_pointer", "interface_pointer",
                             "responses_pointer"):
            ic.unknown(e, ["single", "variables_pointer", "interface_pointer",
                           "responses_pointer"])
    inner_vars = _read_variables(deck, _by_id(deck, "variables", _pointer(
        inner_model, "variables_pointer"), inner_model.line), tx)
    inner_resp = _read_responses(deck, _by_id(deck, "responses", _pointer(
        inner_model, "responses_pointer"), inner_model.line), tx)
    outer_resp = _read_responses(deck, _by_id(deck, "responses", _pointer(
        outer_b, "responses_pointer") or info.get("responses_pointer"), nb.line), tx)
    drv = _read_interface(deck, _by_id(deck, "interface", _pointer(
        inner_model, "interface_pointer"), inner_model.line), tx)
    outer = _read_method(deck, outer_b, outer_resp.names, tx)
    inner = _read_method(deck, inner_b, inner_resp.names, tx)
    if outer.kind != "nl2sol":
        raise InputFileError(deck.path, outer_b.line, "nl2sol as the outer method of the "
                             "nested CUU form")
    inner_name = {"local_reliability": "mean_value", "sampling": "sampling",
                  "polynomial_chaos": "pce"}.get(inner.kind)
    if inner_name is None or inner.opts.get("mpp_search"):
        raise InputFileError(deck.path, inner_b.line, "an inner local_reliability (mean "
                             "value), sampling or polynomial_chaos method")
    pvm = info.get("primary_variable_mapping") or []
    sec = info.get("secondary") or []
    if len(pvm) != len(outer_vars.design) or len(sec) != len(pvm) or outer_vars.uncertain:
        raise InputFileError(deck.path, nb.line, "primary_variable_mapping and "
                             "secondary_variable_mapping naming, for each outer "
                             "continuous_design variable, an inner variable and "
                             "'std_deviation' or 'mean'")
    inner_names = [v.name for v in inner_vars.uncertain]
    stats_ = set(sec)
    if not stats_ <= {"std_deviation", "mean"} or any(p not in inner_names for p in pvm):
        raise InputFileError(deck.path, info.get("secondary_line", nb.line),
                             "mappings onto the inner uncertain variables "
                             f"({', '.join(inner_names)}) and their 'mean' or "
                             "'std_deviation'", " ".join(pvm + sec))
    unmapped = [n for n in inner_names if n not in pvm]
    if unmapped:
        raise InputFileError(deck.path, nb.line, "every inner uncertain variable mapped (the "
                             "cuu step calibrates all its inputs; hold the others as "
                             "continuous_state)", ", ".join(unmapped))
    calibrate = ("mean_std" if stats_ == {"std_deviation", "mean"} else
                 "std" if stats_ == {"std_deviation"} else "mean")
    if calibrate == "mean_std" and len(set(pvm)) * 2 != len(pvm):
        raise InputFileError(deck.path, nb.line, "both mean and std_deviation of every mapped "
                             "variable (or only one statistic for all)")
    m = len(inner_resp.names)
    prm = info.get("primary_response_mapping") or []
    n_out = len(outer_resp.names)
    if len(prm) != n_out * 2 * m:
        raise InputFileError(deck.path, nb.line, f"a primary_response_mapping of {n_out} rows "
                             f"x {2 * m} columns (mean, std of each inner response)")
    if outer_resp.data is None or len(next(iter(outer_resp.data.values()))) != 1:
        raise InputFileError(deck.path, outer_resp.line, "a calibration_data_file with one "
                             "experiment: the targets of the outer calibration terms")
    targets: dict[str, list[float]] = {}
    for row in range(n_out):
        w = prm[row * 2 * m:(row + 1) * 2 * m]
        nz = [j for j, v in enumerate(w) if v != 0]
        if len(nz) != 1 or w[nz[0]] != 1:
            raise InputFileError(deck.path, nb.line, "rows of primary_response_mapping that "
                                 "each select one inner statistic with weight 1")
        r, stat = inner_resp.names[nz[0] // 2], ("mean", "std")[nz[0] % 2]
        t = targets.setdefault(drv.mapping.get(r, r), [0.0, 0.0])
        t[0 if stat == "mean" else 1] = outer_resp.data[outer_resp.names[row]][0]
    for r, (_, s) in targets.items():
        if s <= 0:
            raise InputFileError(deck.path, nb.line, f"a std target of {r!r} (the cuu step "
                                 "takes targets as [mean, std] per response)")
    step: dict[str, Any] = {"name": "cuu", "type": "cuu",
                            "parameters": list(dict.fromkeys(pvm)),
                            "responses": list(targets), "targets": targets,
                            "calibrate": calibrate, "inner": inner_name, "optimizer": "nl2sol",
                            "weighting": "absolute"}
    for dk, sk in (("convergence_tolerance", "tolerance"), ("max_iterations",
                                                              "max_iterations")):
        if dk in outer.opts:
            step[sk] = outer.opts[dk]
    # start: the outer design variables' initial points are the inner statistics
    start = {}
    for v, p, s in zip(outer_vars.design, pvm, sec, strict=True):
        if "initial_point" in v.attrs:
            start[(p, s)] = v.attrs["initial_point"]
    params = []
    for v in inner_vars.uncertain:
        v2 = _Var(v.name, v.group, dict(v.attrs), v.line)
        for (p, s), x0 in start.items():
            if p == v.name:
                key = "means" if s == "mean" else "std_deviations"
                if v.group not in ("normal_uncertain", "lognormal_uncertain"):
                    raise InputFileError(deck.path, v.line, "a normal or lognormal inner "
                                         f"variable for a mapped statistic ({v.name!r})")
                v2.attrs[key] = x0
        params.append(v2)
    fixed = {v.name: v.attrs["initial_state"] for v in inner_vars.state}
    fixed.update({v.name: v.attrs["initial_point"] for v in inner_vars.design})
    inner_resp.names = list(inner_resp.names)
    tx.done()
    return _emit(deck, name, inner.seed or outer.seed, drv, inner_resp, params, fixed, [step],
                 design=set())


def _rotor_input_names(preset: str) -> tuple[str, ...]:
    from .schema import _rotor_inputs

    return _rotor_inputs(preset, "{}")


def _toml(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(int(v)) + ".0" if v.is_integer() and abs(v) < 1e15 else repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, Mapping):
        return "{ " + ", ".join(f"{_key(k)} = {_toml(x)}" for k, x in v.items()) + " }"
    if isinstance(v, Sequence | np.ndarray):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    raise TypeError(type(v))


def _key(k: str) -> str:
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else _toml(k)


def _dakota_order(variables: Sequence[_Var]) -> list[_Var]:
    """Variables in the order Dakota hands them to a direct function and to its correlation
    matrix: by type (:data:`_GROUPS`), deck order within a type."""
    groups = list(_GROUPS)
    return sorted(variables, key=lambda v: groups.index(v.group))


def _emit(deck: Deck, name: str | None, seed: int | None, drv: _Driver, resp: _Responses,
          params: list[_Var], fixed: dict, steps: list[dict], design: set,
          correlation: tuple[list[float], int] | None = None) -> str:
    name = name or Path(deck.path).stem or "deck"
    rename = drv.mapping
    lines = [f"# Translated from the Dakota deck {Path(deck.path).name} by "
             "'rotoruq dakota import'.", "", "[study]", f"name = {_toml(name)}",
             f"seed = {seed if seed is not None else 1}", ""]
    lines.append("[model]")
    outputs = drv.outputs or [rename.get(r, r) for r in resp.names]
    if drv.preset is not None:
        lines.append(f"preset = {_toml(drv.preset)}")
    elif drv.function is not None:
        lines.append(f"function = {_toml(drv.function)}")
        if drv.components:
            lines.append(f"components = {_toml(drv.components)}")
    else:
        assert drv.command is not None
        lines.append(f"command = {_toml(drv.command)}")
        if drv.parameters_format != "standard":
            lines.append(f"parameters_format = {_toml(drv.parameters_format)}")
        for k, v in drv.failure.items():
            lines.append(f"{k} = {_toml(v)}")
        if drv.gradients is not None:
            lines.append(f"gradients = {_toml(drv.gradients)}")
    lines.append(f"responses = {_toml(outputs)}")
    allfixed = {rename.get(k, k): float(v) for k, v in fixed.items()}
    allfixed.update({k: float(v) for k, v in drv.fixed.items()})
    if allfixed:
        lines.append(f"fixed = {_toml(allfixed)}")
    lines.append("")
    known = _rotor_input_names(drv.preset) if drv.preset is not None else None
    start: dict[str, float] = {}
    for v in params:
        # a deck's variable keeps its name; one the driver renames (--map) feeds that input
        target = rename.get(v.name, v.name)
        if known is not None and target not in known:
            raise InputFileError(deck.path, v.line, f"a variable named as an input of the "
                                 f"rotor preset {drv.preset!r}, or --map {v.name}=INPUT in "
                                 "the rotoruq driver string", v.name)
        lines.append(f"[parameters.{_key(v.name)}]")
        if target != v.name:
            lines.append(f"input = {_toml(target)}")
        if v.name in design:
            dist, x0 = _design_distribution(v, deck)
            if x0 is not None:
                start[v.name] = x0
        else:
            dist = _distribution(v, deck)
        for k, x in dist.items():
            lines.append(f"{k} = {_toml(x)}")
        lines.append("")
    if correlation is not None:
        values, line = correlation
        aleatory = [v for v in _dakota_order(params) if v.group in _ALEATORY]
        n = len(aleatory)
        if len(values) != n * n:
            raise InputFileError(deck.path, line, f"an uncertain_correlation_matrix of {n} x "
                                 f"{n} values (the aleatory uncertain variables, in Dakota's "
                                 f"order: {', '.join(v.name for v in aleatory)})",
                                 f"{len(values)} values")
        matrix = np.asarray(values, float).reshape(n, n)
        if not np.array_equal(matrix, np.eye(n)):
            lines.append("[correlation]")
            lines.append(f"parameters = {_toml([v.name for v in aleatory])}")
            lines.append(f"matrix = {_toml([list(map(float, r)) for r in matrix])}")
            lines.append("")
    if resp.data is not None and any(s.get("data") for s in steps):
        lines.append("[data.calibration]")
        for r, col in resp.data.items():
            lines.append(f"{_key(rename.get(r, r))} = {_toml(col)}")
        lines.append("")
    for s in steps:
        if start and s["type"] == "least_squares":
            s = {**s, "x0": start}
        lines.append("[[steps]]")
        for k, x in s.items():
            lines.append(f"{_key(k)} = {_toml(x)}")
        lines.append("")
    return "\n".join(lines)


# --------------------------------------------------------------------------- export
#: step types the exporter writes as Dakota decks
EXPORTABLE = ("sampling", "sensitivity", "mean_value", "reliability", "pce", "least_squares",
              "bayes_calibration", "cuu", "evidence")

_DAKOTA_DIST = {
    "normal": ("normal_uncertain", (("means", "mean"), ("std_deviations", "std"))),
    "truncated_normal": ("normal_uncertain", (("means", "mean"), ("std_deviations", "std"),
                                              ("lower_bounds", "lower"),
                                              ("upper_bounds", "upper"))),
    "lognormal": ("lognormal_uncertain", (("means", "mean"), ("std_deviations", "std"))),
    "uniform": ("uniform_uncertain", (("lower_bounds", "lower"), ("upper_bounds", "upper"))),
    "loguniform": ("loguniform_uncertain", (("lower_bounds", "lower"),
                                            ("upper_bounds", "upper"))),
    "triangular": ("triangular_uncertain", (("modes", "mode"), ("lower_bounds", "lower"),
                                            ("upper_bounds", "upper"))),
    "exponential": ("exponential_uncertain", (("betas", "beta"),)),
    "beta": ("beta_uncertain", (("alphas", "alpha"), ("betas", "beta"),
                                ("lower_bounds", "lower"), ("upper_bounds", "upper"))),
    "gamma": ("gamma_uncertain", (("alphas", "alpha"), ("betas", "beta"))),
    "gumbel": ("gumbel_uncertain", (("alphas", "alpha"), ("betas", "beta"))),
    "weibull": ("weibull_uncertain", (("alphas", "alpha"), ("betas", "beta"))),
    "frechet": ("frechet_uncertain", (("alphas", "alpha"), ("betas", "beta"))),
    "histogram_bin": ("histogram_bin_uncertain", (("abscissas", "abscissas"),
                                                  ("counts", "counts"))),
}
# a lognormal's three forms (Dakota's option_1 .. option_3), one for a whole group
_LOGNORMAL_FORMS = ((("means", "mean"), ("std_deviations", "std")),
                    (("means", "mean"), ("error_factors", "error_factor")),
                    (("lambdas", "lambda"), ("zetas", "zeta")))


def rotoruq_command() -> str:
    """How a deck calls rotoruq: plain ``rotoruq`` when the ``rotoruq`` found on ``PATH`` is
    this installation's console script (the deck then runs on another machine or venv with
    rotoruq on its PATH), else the absolute path of this installation's script, else
    ``<python> -m rotoruq``. ``rotoruq dakota export`` says in a comment which it wrote."""
    import shutil

    script = Path(sys.executable).with_name("rotoruq")
    found = shutil.which("rotoruq")
    if found is not None and script.is_file():
        try:
            same = os.path.samefile(found, script)
        except OSError:
            same = False
        if not same:  # another folder's script that starts this very Python
            try:
                with open(found, "rb") as fh:
                    first = fh.readline(4096).decode("utf-8", "replace")
                same = first.startswith("#!") and first[2:].strip() == sys.executable
            except OSError:
                same = False
        if same:
            return "rotoruq"
    return shlex.quote(str(script)) if script.is_file() else \
        f"{shlex.quote(sys.executable)} -m rotoruq"


def _fmt(x: float) -> str:
    return repr(float(x))


def study_to_decks(study: Any, *, steps: Sequence[str] | None = None, quick: bool = False,
                   data_dir: str | os.PathLike | None = None) -> dict[str, str]:
    """Dakota decks of a study's steps: step name -> deck text.

    Parameters
    ----------
    study : a :class:`rotoruq.study.spec.Study` (from :func:`rotoruq.study.schema.load_study`).
    steps : names of the steps to export (default: every step of a type in
        :data:`EXPORTABLE`); a named step of another type raises InputFileError.
    quick : the steps' ``--quick`` sizes.
    data_dir : where calibration data files (``<step>.dat``) are written for
        ``least_squares`` and ``bayes_calibration`` steps (default: not written, the deck
        names them).

    Returns
    -------
    dict : step name -> the text of a deck whose ``fork`` interface runs the study's model
        through ``rotoruq driver`` (or the study's external command).

    Examples
    --------
    >>> from rotoruq.study.schema import parse_study
    >>> s = parse_study('''[study]
    ... name = "t"
    ... [model]
    ... preset = "gvpm"
    ... responses = ["thrust"]
    ... fixed = { omega = 224.6375 }
    ... [parameters.cla_m03]
    ... distribution = "normal"
    ... mean = 0.108
    ... std = 0.0054
    ... [[steps]]
    ... name = "mv"
    ... type = "mean_value"
    ... ''')
    >>> print(study_to_decks(s)["mv"].split("method")[1].split("variables")[0].strip())
    local_reliability
    """
    from ..steps import step_type

    out = {}
    for st in study.steps:
        if steps is not None and st.name not in steps:
            continue
        if steps is None and st.source is not None:
            continue  # distributions from an earlier step's results: only when asked for
        if st.type not in EXPORTABLE:
            if steps is not None:
                raise InputFileError(None, None, "a step of a type the export writes ("
                                     + ", ".join(EXPORTABLE) + ")", f"{st.name} ({st.type})")
            continue
        opts = dict(st.options)
        if quick:
            opts.update(step_type(st.type).quick)
        try:
            out[st.name] = _deck_for(study, st, opts, data_dir)
        except InputFileError as exc:
            if exc.path != "<string>":
                raise
            raise InputFileError(study.path, st.line, f"{exc.expected} in step {st.name!r}",
                                 exc.found) from None
    return out


def _space_of(study: Any, st: Any) -> tuple[list[str], list[Any]]:
    if st.source is not None:
        raise InputFileError(study.path, st.line, f"step {st.name!r} with its distributions "
                             "in the study file (a 'from' of an earlier step's results is not "
                             "exported)", ".".join(st.source))
    names = list(st.parameters or study.parameter_names)
    specs = {p.name: p for p in study.parameters}
    specs.update({p.name: p for p in st.distributions})
    unknown = [n for n in names if n not in specs]
    if unknown:
        raise InputFileError(study.path, st.line, f"parameters of step {st.name!r} defined in "
                             "[parameters] or in the step's distributions", ", ".join(unknown))
    return names, [specs[n] for n in names]


def _deck_for(study: Any, st: Any, o: dict, data_dir: Any) -> str:
    if st.type == "cuu":
        return _cuu_deck(study, st, o, data_dir)
    names, specs = _space_of(study, st)
    responses = list(st.responses or study.model.responses)
    seed = study.info.seed
    method, resp_extra = _method_text(st, o, responses, names, seed)
    if st.type == "pce" and o.get("dimension_preference"):
        groups = list(_GROUPS)
        kinds = {n: _DAKOTA_DIST[_describe(s)["kind"]][0] for n, s in zip(names, specs,
                                                                         strict=True)}
        ordered = sorted(names, key=lambda n: groups.index(kinds[n]))
        pref = o["dimension_preference"]
        method = method.replace("    variance_based_decomp", "    dimension_preference = "
                                + " ".join(_fmt(pref.get(n, 1.0)) for n in ordered)
                                + "\n    variance_based_decomp", 1)
    if st.type == "least_squares":
        bounds = [_bounds(spec) for spec in specs]
        var_lines = [f"  continuous_design = {len(names)}",
                     "    initial_point = " + " ".join(_fmt(_mean(p)) for p in specs)]
        for k, j in (("lower_bounds", 0), ("upper_bounds", 1)):
            if not all(math.isinf(b[j]) for b in bounds):
                var_lines.append(f"    {k} = " + " ".join(
                    _fmt(max(min(b[j], 1e30), -1e30)) for b in bounds))
        var_lines.append("    descriptors = " + " ".join(f"'{n}'" for n in names))
    elif st.type == "evidence":
        cells = o["intervals"]
        var_lines = _interval_lines(cells)
        # the study's other parameters stay at their means, as the step holds them
        names = list(cells)
    else:
        var_lines = _uncertain_lines(names, specs, getattr(study, "correlation", None))
    renamed = study.renamed_inputs
    # the study's parameters the step leaves out stay at their means (as the runner holds them)
    unused = {renamed.get(p.name, p.name): p.distribution.mean for p in study.parameters
              if p.name not in names}
    fixed = {k: v for k, v in {**unused, **study.model.fixed, **st.fixed}.items()
             if k not in names}
    var_lines += _state_lines(study, fixed)
    if st.type == "sampling" and o.get("design") == "file":
        state = list(fixed.values()) if _state_lines(study, fixed) else []
        method = _given_points_text(o["points"]["file"], names, specs, state)
    driver = (_driver_line(study, fixed, responses, names)
              if study.model.kind != "function" else None)
    kind = "calibration_terms" if st.type in ("least_squares", "bayes_calibration") \
        else "response_functions"
    grads = _gradients_text(study) if st.type in ("mean_value", "reliability",
                                                  "least_squares") else "  no_gradients"
    data_lines = ""
    if kind == "calibration_terms":
        data_lines = _data_text(study, st, o, responses, data_dir)
    return f"""# Dakota deck of the rotoruq study {study.info.name!r}, step {st.name!r} ({st.type}),
# written by 'rotoruq dakota export'.
environment
  tabular_data
    tabular_data_file = '{st.name}.dat.tab'
  output_precision = 16
method
{method}
variables
{chr(10).join(var_lines)}
{_interface_text(study, fixed, responses, names, specs, driver)}responses
  {kind} = {len(responses)}
    descriptors = {' '.join(f"'{r}'" for r in responses)}
{data_lines}{resp_extra}{grads}
  no_hessians
"""


def _gradients_text(study: Any) -> str:
    """The responses' gradient keywords: a test function's own analytic gradient where it has
    one (as the study uses it), else Dakota's forward differences."""
    m = study.model
    if m.kind == "function" and _dakota_functions()[m.function].has_gradient:
        return "  analytic_gradients"
    if m.kind == "external" and getattr(m.external, "gradients", None) == "analytic":
        return "  analytic_gradients"
    return ("  numerical_gradients\n    method_source dakota\n    interval_type forward\n"
            "    fd_step_size = 1e-6")


def _interface_text(study: Any, fixed: Mapping, responses: list[str], names: Sequence[str],
                    specs: Sequence[Any], driver: str | None, ident: str | None = None) -> str:
    """The interface block: ``direct`` for one of Dakota's test functions, else ``fork``
    running the study's model (``rotoruq driver`` or the external command)."""
    head = f"  id_interface = '{ident}'\n" if ident else ""
    m = study.model
    if m.kind == "function":
        _check_function_order(study, names, specs, fixed)
        comps = ("    analysis_components = " + " ".join(f"'{c}'" for c in m.components)
                 + "\n") if m.components else ""
        return (f"interface\n{head}  direct\n    analysis_drivers = '{m.function}'\n"
                + comps)
    if driver is None:
        driver = _driver_line(study, fixed, responses, list(names))
    return (f"interface\n{head}  fork\n    analysis_drivers = '{driver}'\n"
            "    parameters_file = 'params.in'\n    results_file = 'results.out'\n"
            "    file_tag\n")


def _check_function_order(study: Any, names: Sequence[str], specs: Sequence[Any],
                          fixed: Mapping) -> None:
    """Dakota hands a direct function its variables by type (uncertain in its type order,
    then state); the study hands them in its own order. A function that takes them by
    position is exported only where the two orders agree."""
    from .spec import function_variables

    m = study.model
    if _dakota_functions()[m.function].labels:
        return  # read by label, in any order
    groups = list(_GROUPS)
    kinds = {n: _DAKOTA_DIST[_describe(s)["kind"]][0] for n, s in zip(names, specs,
                                                                     strict=True)}
    dakota = sorted(names, key=lambda n: groups.index(kinds[n])) + list(fixed)
    ours = [n for n in function_variables(m, study.parameters) if n in dakota]
    if ours != dakota:
        raise InputFileError(None, None, f"the parameters of a '{m.function}' study in "
                             "Dakota's order of variable types, then the fixed inputs (the "
                             "function takes them by position; Dakota orders them "
                             f"{' '.join(dakota)})", " ".join(ours))


def _interval_lines(cells: Mapping[str, Sequence[Sequence[float]]]) -> list[str]:
    """An evidence step's cells as Dakota's continuous_interval_uncertain variables."""
    flat = [c for n in cells for c in cells[n]]
    return [f"  continuous_interval_uncertain = {len(cells)}",
            "    num_intervals = " + " ".join(str(len(cells[n])) for n in cells),
            "    interval_probabilities = " + " ".join(_fmt(c[2]) for c in flat),
            "    lower_bounds = " + " ".join(_fmt(c[0]) for c in flat),
            "    upper_bounds = " + " ".join(_fmt(c[1]) for c in flat),
            "    descriptors = " + " ".join(f"'{n}'" for n in cells)]


def _state_lines(study: Any, fixed: Mapping) -> list[str]:
    """An external model's fixed inputs as continuous_state variables (its command reads them
    from the parameters file; the rotor driver gets them as --set instead)."""
    if study.model.kind == "preset" or not fixed:
        return []
    return [f"  continuous_state = {len(fixed)}",
            "    initial_state = " + " ".join(_fmt(v) for v in fixed.values()),
            "    descriptors = " + " ".join(f"'{k}'" for k in fixed)]


def _uncertain_lines(names: Sequence[str], specs: Sequence[Any],
                     correlation: Any = None) -> list[str]:
    """Dakota's uncertain variable groups for these parameters (in Dakota's order of types),
    with the ``uncertain_correlation_matrix`` of a correlated study."""
    by_kind: dict[str, list[tuple[str, dict]]] = {}
    for n, spec in zip(names, specs, strict=True):
        d = _describe(spec)
        kind = d.pop("kind")
        if kind not in _DAKOTA_DIST:
            raise InputFileError(None, None, f"a distribution Dakota's deck can state for "
                                 f"{n!r} ({', '.join(_DAKOTA_DIST)})", kind)
        by_kind.setdefault(_DAKOTA_DIST[kind][0], []).append((n, d))
    groups = list(_GROUPS)
    out, order = [], []
    for dk in sorted(by_kind, key=groups.index):
        items = by_kind[dk]
        order += [n for n, _ in items]
        out.append(f"  {dk} = {len(items)}")
        if dk == "lognormal_uncertain":
            fields: tuple = next((f for f in _LOGNORMAL_FORMS
                                  if all(all(b in d for _, b in f) for _, d in items)),
                                 _LOGNORMAL_FORMS[2])
            out.append("    parameters option_" + str(_LOGNORMAL_FORMS.index(fields) + 1))
            for _, d in items:  # a group of mixed forms: by lambda and zeta
                if "lambda" not in d:
                    dist = d.get("_dist")
                    d.setdefault("lambda", getattr(dist, "lambda_", math.nan))
                    d.setdefault("zeta", getattr(dist, "zeta", math.nan))
            fields = fields + (("lower_bounds", "lower"), ("upper_bounds", "upper"))
        else:
            fields = _DAKOTA_DIST[next(k for k, v in _DAKOTA_DIST.items() if v[0] == dk)][1]
        if dk == "histogram_bin_uncertain":
            out.append("    pairs_per_variable = " + " ".join(str(len(d["abscissas"]))
                                                            for _, d in items))
            for key in ("abscissas", "counts"):
                flat = []
                for _, d in items:
                    v = list(d[key])
                    flat += v + ([0.0] if key == "counts" and len(v) < len(d["abscissas"])
                                 else [])
                out.append(f"    {key} = " + " ".join(_fmt(x) for x in flat))
        else:
            for a, b in fields:
                vals = [d.get(b, math.inf if a == "upper_bounds" else
                              0.0 if a == "lower_bounds" else math.nan) for _, d in items]
                if a in ("lower_bounds", "upper_bounds") and all(
                        math.isinf(x) or (a == "lower_bounds" and dk.startswith("lognormal")
                                          and x == 0.0) for x in vals):
                    continue
                if not all(math.isinf(x) for x in vals):
                    out.append(f"    {a} = " + " ".join(_fmt(x) for x in vals))
        out.append("    descriptors = " + " ".join(f"'{n}'" for n, _ in items))
    if correlation is not None:
        aleatory = [n for n in order]
        matrix = correlation.matrix_for(tuple(aleatory))
        if matrix is not None:
            out.append("  uncertain_correlation_matrix =")
            out += ["    " + " ".join(_fmt(x) for x in row) for row in matrix]
    return out


def _cuu_deck(study: Any, st: Any, o: dict, data_dir: Any) -> str:
    """The nested model of the thesis's CUU: an outer nl2sol on the calibrated statistics,
    mapped onto the inner uncertain variables' means / std deviations, an inner mean value
    (or LHS, or PCE by quadrature) method. Relative weighting is the same least squares with
    each mapping row weighted by 1 / |target| and the data t / |t|."""
    if isinstance(o["targets"], str):
        raise InputFileError(study.path, st.line, "targets given as numbers in the study file "
                             "(not from an earlier step)", o["targets"])
    names, specs = _space_of(study, st)
    for n, spec in zip(names, specs, strict=True):
        if spec.kind not in ("normal", "lognormal"):
            raise InputFileError(study.path, st.line, f"a normal or lognormal {n!r} (Dakota "
                                 "maps a design variable onto its mean / std_deviation)",
                                 spec.kind)
    responses = list(st.responses or study.model.responses)
    stats_ = {"std": ["std"], "mean": ["mean"], "mean_std": ["mean", "std"]}[o["calibrate"]]
    outer = [(n, s) for n in names for s in stats_]
    x0 = [float(getattr(spec.distribution, s)) for spec in specs for s in stats_]
    rows, data, tnames = [], [], []
    relative = o.get("weighting", "relative") == "relative"
    for r, (tm, ts) in o["targets"].items():
        for s in stats_:
            t = float(tm if s == "mean" else ts)
            w = 1.0 / abs(t) if relative and t != 0 else 1.0
            row = [0.0] * (2 * len(responses))
            row[2 * responses.index(r) + (0 if s == "mean" else 1)] = w
            rows.append(row)
            data.append(t * w)
            tnames.append(f"{s}_{r}")
    if data_dir is not None:
        Path(data_dir, f"{st.name}.dat").write_text(" ".join(_fmt(x) for x in data) + "\n")
    inner = o.get("inner") or "mean_value"
    seed = study.info.seed
    if inner == "mean_value":
        inner_method = "  local_reliability"
        inner_grads = ("  numerical_gradients\n    method_source dakota\n"
                       "    interval_type central\n    fd_step_size = 1e-6")
    elif inner == "sampling":
        inner_method = f"  sampling\n    sample_type lhs\n    samples = 200\n    seed = {seed}"
        inner_grads = "  no_gradients"
    else:
        inner_method = "  polynomial_chaos\n    quadrature_order = 3"
        inner_grads = "  no_gradients"
    fixed = {k: v for k, v in {**study.model.fixed, **st.fixed}.items() if k not in names}
    lo = [1e-6 * x if s == "std" else -1e30 for (_, s), x in zip(outer, x0, strict=True)]
    mapping = "\n".join("      " + " ".join(_fmt(v) for v in row) for row in rows)
    tol = f"\n    convergence_tolerance = {o['tolerance']!r}" if o.get("tolerance") else ""
    iters = (f"\n    max_iterations = {o['max_iterations']}" if o.get("max_iterations")
             else "")
    return f"""# Dakota deck of the rotoruq study {study.info.name!r}, step {st.name!r} (cuu: nested
# model, {'relative' if relative else 'absolute'} residuals), written by 'rotoruq dakota export'.
environment
  top_method_pointer = 'OUTER'
  output_precision = 16
method
  id_method = 'OUTER'
  nl2sol{tol}{iters}
  model_pointer = 'NESTED'
model
  id_model = 'NESTED'
  nested
    sub_method_pointer = 'INNER'
    primary_variable_mapping = {' '.join(f"'{n}'" for n, _ in outer)}
    secondary_variable_mapping = {' '.join("'std_deviation'" if s == "std" else "'mean'"
                                           for _, s in outer)}
    primary_response_mapping =
{mapping}
  variables_pointer = 'OUTER_V'
  responses_pointer = 'OUTER_R'
variables
  id_variables = 'OUTER_V'
  continuous_design = {len(outer)}
    initial_point = {' '.join(_fmt(x) for x in x0)}
    lower_bounds = {' '.join(_fmt(x) for x in lo)}
    descriptors = {' '.join(f"'{s}_{n}'" for n, s in outer)}
responses
  id_responses = 'OUTER_R'
  calibration_terms = {len(rows)}
    descriptors = {' '.join(f"'{t}'" for t in tnames)}
  calibration_data_file = '{st.name}.dat'
    freeform
    num_experiments = 1
  numerical_gradients
    method_source dakota
    interval_type forward
    fd_step_size = 1e-6
  no_hessians
method
  id_method = 'INNER'
{inner_method}
  model_pointer = 'INNER_M'
model
  id_model = 'INNER_M'
  single
    interface_pointer = 'MODEL'
  variables_pointer = 'INNER_V'
  responses_pointer = 'INNER_R'
variables
  id_variables = 'INNER_V'
{chr(10).join(_uncertain_lines(names, specs) + _state_lines(study, fixed))}
{_interface_text(study, fixed, responses, names, specs, None, "MODEL")}responses
  id_responses = 'INNER_R'
  response_functions = {len(responses)}
    descriptors = {' '.join(f"'{r}'" for r in responses)}
{inner_grads}
  no_hessians
"""


def _describe(spec: Any) -> dict:
    out: dict[str, Any] = {"kind": spec.kind, "_dist": spec.distribution}
    for k, v in spec.params.items():
        out[k] = [float(x) for x in v] if isinstance(v, tuple | list) else float(v)
    return out


def _mean(spec: Any) -> float:
    return float(spec.distribution.mean)


def _bounds(spec: Any) -> tuple[float, float]:
    lo, hi = spec.distribution.bounds
    return float(lo), float(hi)


def _driver_line(study: Any, fixed: Mapping, responses: list[str],
                 names: Sequence[str] = ()) -> str:
    m = study.model
    if m.kind != "preset":
        fixed = {}
    sets = " ".join(f"--set {k}={float(v)!r}" for k, v in fixed.items())
    renamed = {k: v for k, v in getattr(study, "renamed_inputs", {}).items() if k in names}
    if m.kind == "preset":
        maps = "".join(f" --map {k}={v}" for k, v in renamed.items())
        return f"{rotoruq_command()} driver --preset {m.preset} {sets}{maps}".strip()
    assert m.external is not None
    if renamed:
        raise InputFileError(None, None, "parameters named as the external model's inputs "
                             "(its command reads the deck's names; input = ... is not "
                             "exported)", ", ".join(renamed))
    if m.external.parameters_format != "standard" or m.external.templates:
        raise InputFileError(None, None, "an external model with standard parameters files "
                             "and no templates (the exported deck calls its command)")
    return " ".join(shlex.quote(a) for a in m.external.command)


def _levels_text(o: dict, key: str, responses: list[str]) -> str:
    lv = o.get(key)
    if not lv:
        return ""
    flat, counts = [], []
    for r in responses:
        v = np.atleast_1d(lv.get(r, [])) if isinstance(lv, Mapping) else np.atleast_1d(lv)
        flat += [float(x) for x in v]
        counts.append(len(v))
    return (f"\n    {key} = " + " ".join(_fmt(x) for x in flat)
            + f"\n    num_{key} = " + " ".join(str(c) for c in counts))


def _mappings_text(o: dict, responses: list[str]) -> str:
    """A step's level mappings as a Dakota method block's keywords."""
    text = "\n    distribution complementary" if o.get("distribution") == "ccdf" else ""
    text += "".join(_levels_text(o, k, responses) for k in _LEVELS)
    if o.get("compute") and o.get("response_levels"):
        text += f"\n    compute {o['compute']}"
    return text


def _method_text(st: Any, o: dict, responses: list[str], names: list[str],
                 seed: int) -> tuple[str, str]:
    t = st.type
    if t in ("sampling", "sensitivity"):
        design = o.get("design") or "lhs"
        note = ""
        if design not in ("lhs", "random"):
            # Dakota's sampling has no low-discrepancy sequences: the same estimator on LHS
            note = (f"    # rotoruq's design '{design}' has no Dakota sample_type: LHS "
                    "(the same estimator, its own statistical error)\n")
            design = "lhs"
        n = o.get("n_samples") or _default(t, "n_samples")
        vbd = "\n    variance_based_decomp" if t == "sensitivity" else ""
        return (f"  sampling\n{note}    sample_type {design}\n    samples = {n}\n"
                f"    seed = {seed}{vbd}" + _mappings_text(o, responses), "")
    if t == "mean_value":
        return ("  local_reliability" + _mappings_text(o, responses), "")
    if t == "reliability":
        integ = o.get("integration") or "first_order"
        approx = o.get("approximation") or "none"
        return ("  local_reliability\n    mpp_search "
                + ("no_approx" if approx == "none" else approx)
                + _mappings_text(o, responses) + f"\n    integration {integ}", "")
    if t == "pce":
        order = o.get("order") or _default(t, "order")
        est = o.get("estimator") or "quadrature"
        if est == "quadrature":
            return (f"  polynomial_chaos\n    quadrature_order = {order + 1}\n"
                    "    variance_based_decomp" + _pce_samples_text(o, seed)
                    + _mappings_text(o, responses), "")
        if est in ("sampling", "regression"):
            # the method's default: twice the terms of the total-order basis
            n = (o.get("n_samples") or _default(t, "n_samples")
                 or 2 * math.comb(order + len(names), len(names)))
            key = "expansion_samples" if est == "sampling" else "collocation_points"
            return (f"  polynomial_chaos\n    expansion_order = {order}\n"
                    f"    {key} = {n}\n    seed = {seed}\n"
                    "    variance_based_decomp" + _pce_samples_text(o, None)
                    + _mappings_text(o, responses), "")
        raise InputFileError(None, None, "a pce step by quadrature, regression or sampling",
                             est)
    if t == "evidence":
        n = o.get("n_samples") or _default(t, "n_samples")
        opt = o.get("optimizer") or _default(t, "optimizer")
        # rotoruq's "sampling" optimizer is Dakota's lhs; its "ego" Dakota's ego
        how = ("    lhs\n" f"    samples = {n}\n" if opt == "sampling" else "    ego\n")
        return ("  global_evidence\n" + how + f"    seed = {seed}"
                + _mappings_text(o, responses), "")
    if t == "least_squares":
        lines = ["  nl2sol"]
        if o.get("tolerance") is not None:
            lines.append(f"    convergence_tolerance = {o['tolerance']!r}")
        if o.get("max_iterations") is not None:
            lines.append(f"    max_iterations = {o['max_iterations']}")
        if o.get("max_function_evaluations") is not None:
            lines.append(f"    max_function_evaluations = {o['max_function_evaluations']}")
        return "\n".join(lines), ""
    # bayes_calibration
    sampler = o.get("sampler") or "dram"
    burn = int(o.get("burn_in") or 0)
    n = int(o.get("n_samples") or _default(t, "n_samples"))
    # Dakota 6.24 reads these in this order only (the sampler after the emulator)
    lines = ["  bayes_calibration queso", f"    chain_samples = {n + burn}", f"    seed = {seed}"]
    if (o.get("emulator") or "gp") == "gp":
        ne = o.get("n_emulator_samples") or _default(t, "n_emulator_samples")
        lines += ["    emulator", "      gaussian_process surfpack",
                  f"      build_samples = {ne}"]
    lines.append(f"    {sampler}")
    lines.append("    proposal_covariance "
                 + ("prior" if (o.get("proposal") or "hessian") == "prior" else "derivatives"))
    lines.append(f"    burn_in_samples = {burn}")
    return "\n".join(lines), ""


def _pce_samples_text(o: dict, seed: int | None) -> str:
    n = o.get("samples_on_expansion")
    if not n:
        return ""
    return f"\n    samples_on_emulator = {n}" + (f"\n    seed = {seed}" if seed is not None
                                                    else "")


def _given_points_text(path: str, names: list[str], specs: Sequence[Any],
                       state: Sequence[float]) -> str:
    """A ``design = "file"`` sampling step as Dakota's ``list_parameter_study`` over the same
    points, inline. A parameter study's points give every variable (uncertain, then the
    state variables' fixed values) by position, in Dakota's own order: uncertain variables
    grouped by distribution in the order of its variables block (:data:`_GROUPS`), not the
    deck's."""
    from ..evaluation.tabular import read_table

    groups = list(_GROUPS)
    rank = {n: groups.index(_DAKOTA_DIST[_describe(sp)["kind"]][0])
            for n, sp in zip(names, specs, strict=True)}
    order = sorted(names, key=lambda n: rank[n])  # stable: deck order within a group
    x = read_table(path).require(order, "the step's inputs")
    rows = "\n".join("      " + " ".join(_fmt(v) for v in [*row, *state]) for row in x)
    return ("  # the given points of " + Path(path).name + "\n  list_parameter_study\n"
            "    list_of_points =\n" + rows)


def _default(step_type_name: str, option: str) -> Any:
    from ..steps import step_type
    from ..steps.options import SIGNATURE, signature_default

    st = step_type(step_type_name)
    opt = st.options[option]
    if opt.default is SIGNATURE:
        return signature_default(opt.method or str(st.method), opt.param or option)
    return opt.default


def _data_text(study: Any, st: Any, o: dict, responses: list[str], data_dir: Any) -> str:
    if st.data is None or st.data not in study.data:
        raise InputFileError(None, None, f"a data set for step {st.name!r}", str(st.data))
    rows = np.asarray(study.data[st.data].matrix(responses), float)
    noise = o.get("noise_std")
    variance = ""
    if noise:
        sd = np.array([float(noise[r]) if isinstance(noise, Mapping) else float(noise)
                       for r in responses])
        rows = np.column_stack([rows, np.broadcast_to(sd**2, rows.shape)])
        variance = "\n    variance_type = 'scalar'"
    fname = f"{st.name}.dat"
    if data_dir is not None:
        text = "\n".join(" ".join(_fmt(x) for x in row) for row in rows) + "\n"
        Path(data_dir, fname).write_text(text)
    return (f"  calibration_data_file = '{fname}'\n    freeform\n"
            f"    num_experiments = {len(rows)}{variance}\n")


# --------------------------------------------------------------------------- the table
#: What each translated method becomes (the step type :func:`_step` writes).
METHOD_STEPS = {"sampling": "`sampling` step (`sensitivity` with `variance_based_decomp`)",
                "local_reliability": "`mean_value` step (`reliability` with an MPP search)",
                "polynomial_chaos": "`pce` step (quadrature or regression)",
                "global_evidence": "`evidence` step",
                "nl2sol": "`least_squares` step, `optimizer = \"nl2sol\"`",
                "bayes_calibration": "`bayes_calibration` step (QUESO's samplers)"}
#: What each translated variable type becomes.
VARIABLE_KINDS = {g: ("fixed input (its `initial_state`)" if g == "continuous_state" else
                      "calibrated input of `least_squares`, else a fixed input"
                      if g == "continuous_design" else
                      "interval cells of the `evidence` step"
                      if g == "continuous_interval_uncertain" else
                      f"`distribution = \"{g.removesuffix('_uncertain')}\"`")
                  for g in _GROUPS}


def keyword_table() -> str:
    """The "Coming from Dakota" tables (Markdown), generated from the translator's own lists:
    the methods and variable types translated and to what, each method's keywords, the
    keywords accepted and ignored (Dakota's output, scheduling, cache), and the aliases read.

    Examples
    --------
    >>> "| `sampling` |" in keyword_table()
    True
    """
    rows = ["| Dakota method | becomes | keywords read |", "|---|---|---|"]
    for m, step in METHOD_STEPS.items():
        keys = ", ".join(f"`{k}`" for k in _ALLOWED[m])
        rows.append(f"| `{m}` | {step} | {keys} |")
    rows += ["", "| Dakota variables | becomes | attributes read |", "|---|---|---|"]
    for g, what in VARIABLE_KINDS.items():
        attrs = ", ".join(f"`{a}`" for a in ("descriptors", *_GROUPS[g][1]))
        rows.append(f"| `{g}` | {what} | {attrs} |")
    rows.append("| `uncertain_correlation_matrix` | the `[correlation]` table | |")
    rows += ["", "| block | read and left out (one note lists them) |", "|---|---|"]
    for block, words in OUTPUT_ONLY.items():
        rows.append(f"| `{block}` | " + ", ".join(f"`{w}`" for w in sorted(words)) + " |")
    rows += ["", "| alias | read as |", "|---|---|"]
    rows += [f"| `{a}` | `{k}` |" for a, k in sorted(ALIASES.items())]
    return "\n".join(rows)
