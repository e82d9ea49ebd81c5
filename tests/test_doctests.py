"""The estimators' docstrings are numpydoc with a runnable Examples section, and the examples pass.

Each example runs on a tiny matrix in well under a second and prints shapes, booleans or values
rounded far from a rounding boundary, so it passes under any BLAS.
"""

import doctest
import importlib
import inspect

import pytest
from sklearn.base import BaseEstimator

import nldr.impute
import nldr.model_selection
import nldr.robust_kpca

#: module -> its estimator classes
ESTIMATORS = {
    "nldr.impute._regularizer": ["KernelRegularizerImputer"],
    "nldr.impute._manifold": ["RobustKernelPCAImputer", "DecompositionDenoiser"],
    "nldr.impute._linear": ["PPCAImputer", "SoftImputer", "RobustPCAImputer"],
    "nldr.impute._kernel_pca": ["PKPCAImputer", "RKPCAImputer"],
    "nldr.impute._neighbours": ["NearestNeighbourImputer"],
    "nldr.impute._gplvm": ["GPLVMImputer"],
    "nldr.robust_kpca": ["RobustKernelPCA"],
    "nldr.model_selection._search": ["HoldoutSearch"],
}
#: numpydoc sections every estimator's class docstring has, in this order
SECTIONS = ("Parameters", "Attributes", "See Also", "Notes", "Examples")


def _sections(doc: str) -> list[str]:
    lines = inspect.cleandoc(doc).splitlines()
    return [
        line.strip()
        for line, under in zip(lines, lines[1:], strict=False)
        if under.strip() and set(under.strip()) == {"-"} and len(under.strip()) == len(line.strip())
    ]


def _classes():
    for module, names in ESTIMATORS.items():
        for name in names:
            yield module, name


@pytest.mark.parametrize(("module", "name"), list(_classes()))
def test_estimator_docstring_has_the_numpydoc_sections(module, name):
    cls = getattr(importlib.import_module(module), name)
    found = _sections(cls.__doc__ or "")
    missing = [s for s in SECTIONS if s not in found]
    assert not missing, f"{module}.{name}'s docstring lacks {missing}"
    assert [s for s in found if s in SECTIONS] == list(SECTIONS), f"{name}: sections out of order: {found}"


def test_every_public_estimator_is_listed():
    listed = {name for names in ESTIMATORS.values() for name in names}
    public = set()
    for package in (nldr.impute, nldr.model_selection, nldr.robust_kpca):
        for name in getattr(package, "__all__", []):
            obj = getattr(package, name)
            if inspect.isclass(obj) and issubclass(obj, BaseEstimator):
                public.add(name)
    assert public <= listed, f"estimators without a checked docstring: {sorted(public - listed)}"


def test_section_finder_sees_a_missing_examples_section():
    doc = """Summary.

    Parameters
    ----------
    a : int

    Examples
    --------
    >>> 1
    1
    """
    assert _sections(doc) == ["Parameters", "Examples"]
    assert "Examples" not in _sections(doc.replace("Examples\n    --------", "Example"))


@pytest.mark.parametrize("module", list(ESTIMATORS))
def test_examples_run(module):
    if module == "nldr.impute._gplvm":
        pytest.importorskip("GPy", reason="GPLVMImputer's example needs GPy (pip install 'nldr[peers]')")
    mod = importlib.import_module(module)
    finder = doctest.DocTestFinder()
    runner = doctest.DocTestRunner(optionflags=doctest.NORMALIZE_WHITESPACE)
    names = {f"{module}.{name}" for name in ESTIMATORS[module]}
    tests = [t for t in finder.find(mod) if t.examples]
    without = names - {t.name for t in tests}
    assert not without, f"no examples found for {sorted(without)}"
    for test in tests:
        runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{result.failed} of {result.attempted} doctest examples failed in {module}"
