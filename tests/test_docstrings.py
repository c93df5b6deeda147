"""Every public parameter is a numpydoc entry, and every public docstring renders.

numpydoc's own validation (``numpydoc.validate.validate``) runs on every public name of
``rotoruq._PUBLIC``: each function; each class (its constructor's parameters are documented in
the class docstring) and each of its public methods and properties, its own and those it
inherits from rotoruq base classes; the names a public submodule (``rq.errors``,
``rq.presets``) adds; and the names of the public subpackages (``rotoruq.params``,
``rotoruq.mbdyn``, ...: ``SUBPACKAGES`` of docs/_ext/public_api.py) that the top level does
not re-export. A test fails on

- GL08: no docstring;
- PR01: a parameter that is not documented (in ``Parameters`` or ``Other Parameters``; the
  fields of a dataclass may be documented under ``Attributes``, the section a result's reader
  looks in; a parameter whose name starts with ``_`` is not public);
- PR02: a documented parameter that does not exist (often a line of text that reads as an
  entry, ``word : text``);
- PR03: the parameters documented in another order than the signature's;
- PR10: ``name: type`` without the space before the colon (numpydoc then reads no entry);
- GL06, GL07: an unknown section, or sections in the wrong order.

``test_docstring_renders`` parses each docstring as numpydoc turns it into reST (what the API
pages show) and fails on a formatting problem (a broken definition list, unexpected
indentation, an unterminated inline literal), the problems that made
``docs/_ext/plain_docstrings.py`` show a docstring as raw text. The wrong-type-name checks
(PR06) and the style checks (PR05, PR08: a full stop, a capital letter) are not enforced.

Skipped, with the reason, when numpydoc is not installed (the ``test`` and ``docs`` extras have
it).
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import sys
from pathlib import Path

import pytest

import rotoruq

numpydoc_validate = pytest.importorskip(
    "numpydoc.validate", reason="numpydoc is not installed (pip install -e '.[test]')")
from numpydoc.docscrape import get_doc_object  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs" / "_ext"))
import public_api  # noqa: E402  (the API pages' list of public subpackages)

SUBPACKAGES = public_api.SUBPACKAGES

#: the checks that fail a test
CHECKS = ("GL06", "GL07", "GL08", "PR01", "PR02", "PR03", "PR10")

def _public_objects() -> dict[str, object]:
    """Importable path -> object for every name the checks cover (see the module docstring)."""
    found: dict[str, object] = {}
    seen: set[int] = set()

    def add(path: str, obj: object) -> None:
        if id(obj) in seen:  # an inherited method is checked once, under its first class
            return
        seen.add(id(obj))
        found[path] = obj
        if inspect.isclass(obj):
            members: dict[str, object] = {}
            for klass in obj.__mro__:
                if klass.__module__.startswith("rotoruq"):
                    for name, value in vars(klass).items():
                        members.setdefault(name, value)
            for name, value in members.items():
                raw = value.__func__ if isinstance(value, staticmethod | classmethod) else value
                if not name.startswith("_") and (inspect.isfunction(raw)
                                                 or isinstance(raw, property)):
                    add(f"{path}.{name}", raw)

    top = set(rotoruq.__all__)
    for name in rotoruq._PUBLIC:
        obj = getattr(rotoruq, name)
        if inspect.ismodule(obj):
            for member in getattr(obj, "__all__", ()):
                value = getattr(obj, member)
                if member not in top and (inspect.isclass(value) or inspect.isfunction(value)):
                    add(f"{obj.__name__}.{member}", value)
        elif inspect.isclass(obj) or inspect.isfunction(obj):
            add(f"rotoruq.{name}", obj)
    # the public subpackages' own names, documented on the API pages under their full names
    for sub in SUBPACKAGES:
        module = importlib.import_module(sub)
        for member in module.__all__:
            value = getattr(module, member)
            if member not in top and (inspect.isclass(value) or inspect.isfunction(value)):
                add(f"{sub}.{member}", value)
    return found


PUBLIC = _public_objects()


class _Validator(numpydoc_validate.Validator):
    """numpydoc's validator, with the dataclass fields of ``Attributes`` counted as documented
    and private (``_name``) parameters left out. A method that overrides a documented one
    without a docstring of its own shows the one it overrides (``inspect.getdoc``, as autodoc
    does), which is checked against its own signature."""

    def __init__(self, obj_name: str):
        super().__init__(get_doc_object(numpydoc_validate.Validator._load_obj(obj_name)))
        if not inspect.isclass(self.obj):
            self.raw_doc = inspect.getdoc(self.obj) or ""

    @property
    def signature_parameters(self):
        if inspect.isclass(self.obj) and getattr(self.obj, "_is_protocol", False):
            return ()  # a Protocol (Model) is never constructed
        return tuple(p for p in super().signature_parameters
                     if not p.lstrip("*").startswith("_"))

    def attribute_names(self) -> set[str]:
        if not (inspect.isclass(self.obj) and dataclasses.is_dataclass(self.obj)):
            return set()
        return {n.strip() for names, _, _ in self.doc["Attributes"] for n in names.split(",")}

    @property
    def parameter_mismatches(self):
        signature = self.signature_parameters
        documented = tuple(p.replace("\\", "") for p in self.doc_all_parameters)
        errs = []
        missing = set(signature) - set(documented) - self.attribute_names()
        if missing:
            errs.append(numpydoc_validate.error("PR01", missing_params=str(sorted(missing))))
        extra = set(documented) - set(signature)
        if extra:
            errs.append(numpydoc_validate.error("PR02", unknown_params=str(sorted(extra))))
        if not missing and not extra and set(documented) == set(signature) \
                and documented != signature:
            errs.append(numpydoc_validate.error(
                "PR03", actual_params=signature, documented_params=documented))
        return errs


#: checks computed here, with the validator above, in place of numpydoc's own
OWN_CHECKS = ("GL08", "PR01", "PR02", "PR03")


def _errors(path: str) -> list[tuple[str, str]]:
    """The failing checks of ``path``: numpydoc's validation report (``validate``) for the
    formatting checks, and the parameter checks of :class:`_Validator` (which reads the same
    docstring with numpydoc's parser)."""
    found = [(code, msg) for code, msg in numpydoc_validate.validate(path)["errors"]
             if code in CHECKS and code not in OWN_CHECKS]
    validator = _Validator(path)
    if not validator.raw_doc:
        return [numpydoc_validate.error("GL08")] + found
    return list(validator.parameter_mismatches) + found


def test_the_checks_cover_the_public_api():
    assert len(PUBLIC) > 300, len(PUBLIC)
    assert "rotoruq.calibrate_bayes" in PUBLIC and "rotoruq.BayesResult.save" in PUBLIC
    assert "rotoruq.errors.StoreError" in PUBLIC  # a name rq.errors adds
    assert "rotoruq.params.NatafModel" in PUBLIC  # a subpackage's name


@pytest.mark.parametrize("path", list(PUBLIC))
def test_docstring_documents_every_parameter(path):
    errors = _errors(path)
    assert not errors, f"{path}:\n" + "\n".join(f"  {c}: {m}" for c, m in errors)


def _plain_docstrings():
    sys.path.insert(0, str(ROOT / "docs" / "_ext"))
    try:
        return importlib.import_module("plain_docstrings")
    finally:
        sys.path.remove(str(ROOT / "docs" / "_ext"))


def _rendered(obj) -> str:
    """The reST numpydoc makes of ``obj``'s docstring, as the API pages get it (with the
    docs' escaping of plain-text ``|``)."""
    from numpydoc.docscrape_sphinx import get_doc_object as sphinx_doc

    config = {"show_class_members": False, "class_members_toctree": False}
    text = str(sphinx_doc(obj, config=config))
    return "\n".join(_plain_docstrings()._escape_bars(line) for line in text.splitlines())


@pytest.mark.parametrize("path", list(PUBLIC))
def test_docstring_renders(path):
    pytest.importorskip("sphinx", reason="Sphinx is not installed (numpydoc's reST needs it)")
    text = _rendered(PUBLIC[path])
    problems = _plain_docstrings()._problems(text, None)
    assert not problems, f"{path} is not valid reST once numpydoc has read it:\n" + "\n".join(
        problems) + "\n---\n" + text
