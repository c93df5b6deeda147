"""Seeded structural mutants of the bundled study files (the fuzz target of
tests/test_fuzz_mutants.py): each mutant is the TOML of a bundled study with a few edits of its
parsed document: a value of another type, a value nested in arrays or tables, a huge, tiny,
NaN, infinite or negative number, a key removed, a key added or renamed."""

from __future__ import annotations

import json
import math
import re
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

STUDIES = Path(__file__).resolve().parents[1] / "src" / "rotoruq" / "studies"
BARE = re.compile(r"^[A-Za-z0-9_-]+$")
NUMBERS = [1e308, -1e308, float("nan"), float("inf"), float("-inf"), 0, 0.0, -1, -1.5, 1e-320,
           2**63 - 1, -(2**63), 10**6, 3, 1, 0.5]
OTHERS: list[Any] = ["", "x", "normal", "sampling", "../../etc", "a" * 300, True, False, [],
                     [1, 2], ["a"], [[1.0, 2.0], [3.0]], [[[0.5]]], {}, {"a": 1},
                     {"lower": 1.0}, [{"name": "x"}]]
EXTRA_KEYS = ["zz_extra", "name", "type", "from", "n_samples", "seed", "distribution", "mean",
              "std", "lower", "upper", "responses", "response_levels", "radius", "fixed",
              "model", "steps", "data", "select", "column", "label", "unit"]


def bundled() -> dict[str, dict]:
    """The bundled studies' parsed documents, by file name."""
    return {p.name: tomllib.loads(p.read_text(encoding="utf-8"))
            for p in sorted(STUDIES.glob("*.toml"))}


def _key(k: str) -> str:
    return k if BARE.match(k) else json.dumps(k, ensure_ascii=False)


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False).replace("\x7f", "\\u007f")
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + "}"
    return json.dumps(str(v))  # a date: as text


def to_toml(doc: dict) -> str:
    """TOML text for ``doc``: tables as ``[a.b]`` sections, arrays of tables as ``[[a]]``,
    everything else inline (so errors have lines to name)."""
    lines: list[str] = []

    def table(d: dict, prefix: list[str]) -> None:
        subs = []
        for k, v in d.items():
            if isinstance(v, dict) and v:
                subs.append((k, v, False))
            elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
                subs.append((k, v, True))
            else:
                lines.append(f"{_key(k)} = {_value(v)}")
        for k, v, many in subs:
            name = ".".join(_key(p) for p in [*prefix, k])
            for item in (v if many else [v]):
                lines.append("")
                lines.append(f"[[{name}]]" if many else f"[{name}]")
                table(item, [*prefix, k])

    table(doc, [])
    return "\n".join(lines) + "\n"


def _paths(doc: Any, here: tuple = ()) -> list[tuple]:
    """Every place in ``doc`` (a path of keys and indices) holding a value."""
    out = []
    if isinstance(doc, dict):
        for k, v in doc.items():
            out.append((*here, k))
            out.extend(_paths(v, (*here, k)))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            out.append((*here, i))
            out.extend(_paths(v, (*here, i)))
    return out


def _pick(rng: np.random.Generator, seq: list) -> Any:
    return seq[int(rng.integers(len(seq)))]


def mutate(doc: dict, rng: np.random.Generator, n_edits: int) -> dict:
    """``doc`` (a deep copy) with ``n_edits`` random edits."""
    doc = json.loads(json.dumps(doc, default=str))
    for _ in range(n_edits):
        paths = _paths(doc)
        if not paths:
            break
        path = _pick(rng, paths)
        parent: Any = doc
        for p in path[:-1]:
            parent = parent[p]
        last = path[-1]
        old = parent[last]
        op = _pick(rng, ["number", "other", "nest", "drop", "add", "rename", "number", "other"])
        if op == "number":
            parent[last] = _pick(rng, NUMBERS)
        elif op == "other":
            parent[last] = json.loads(json.dumps(_pick(rng, OTHERS)))
        elif op == "nest":
            parent[last] = _pick(rng, [[old], [[old]], {"x": old}, [old, old]])
        elif op == "drop":
            del parent[last]
        elif op == "add":
            target = old if isinstance(old, dict) else parent
            if isinstance(target, dict):
                target[_pick(rng, EXTRA_KEYS)] = json.loads(
                    json.dumps(_pick(rng, [*NUMBERS[:4], *OTHERS]), default=str))
        elif op == "rename" and isinstance(parent, dict):
            new = _pick(rng, EXTRA_KEYS)
            if new not in parent:
                parent[new] = parent.pop(last)
    return doc


def mutants(seed: int, n: int) -> list[tuple[str, str]]:
    """``n`` (bundled study name, mutated TOML text) pairs, the same for the same seed."""
    rng = np.random.default_rng(seed)
    docs = bundled()
    names = sorted(docs)
    out = []
    for _ in range(n):
        name = _pick(rng, names)
        out.append((name, to_toml(mutate(docs[name], rng, int(rng.integers(1, 4))))))
    return out
