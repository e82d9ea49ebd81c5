"""The library's public surface: the ``__all__`` of each public module (no ``_`` in its dotted path).

A name that appears in, or leaves, a module's ``__all__`` fails here until the list below says so and
an API page (``docs/api/*.md``) renders it, by its module (``::: nldr.x``, which renders the module's
``__all__``) or by name (``::: nldr.x.Name``). Everything else in the library is private: modules,
packages and names with a leading underscore, free to change without notice.
"""

from __future__ import annotations

import importlib
import pkgutil
import re
import types

from conftest import REPO

import nldr

#: Public module -> its ``__all__``, sorted. Change this list with the API pages, deliberately.
PUBLIC = {
    "nldr": [],
    "nldr.data_terms": ["DataTerm", "Huber", "MaskedHuber", "MaskedLeastSquares", "huber_loss"],
    "nldr.datasets": [
        "DataError", "FILES", "MOCAP_SEQUENCES", "MocapSequence", "OIL_SPLITS", "default_data_dir", "fetch",
        "load_mocap", "load_oil", "load_oil_rows", "registry", "verify_present",
    ],
    "nldr.experiments": [
        "EXPERIMENTS", "Experiment", "Job", "JobOutput", "figure_owner", "get", "summary_stats",
    ],
    "nldr.experiments.base": [
        "Experiment", "Job", "JobOutput", "SD_DDOF", "float_counts", "is_measured", "join_measured",
        "split_measured", "split_measured_table", "summary_stats",
    ],
    "nldr.experiments.notebook": [
        "Located", "cached", "load_config", "locate", "merge_config", "need", "repo_root", "timing_path",
    ],
    "nldr.impute": [
        "DecompositionDenoiser", "KernelRegularizerImputer", "NearestNeighbourImputer", "PKPCAImputer",
        "PPCAImputer", "RKPCAImputer", "RobustKernelPCAImputer", "RobustPCAImputer", "SoftImputer",
    ],
    "nldr.kernels": [
        "center_cross_kernel", "center_kernel", "d_max_width", "d_med_width", "rbf_kernel", "rbf_kernel_vjp",
        "squared_distances",
    ],
    "nldr.model_selection": [
        "EntryFolds", "HoldoutSearch", "RobustScaleDelta", "holdout_folds", "median_gamma", "robust_scale",
    ],
    "nldr.nrsfm": [
        "CameraFrameVariables", "NRSfMSelection", "OrthographicReprojection", "Reconstruction", "TNHResult",
        "TNHSolveError", "camera_error", "center_per_frame", "e3d", "initialize_cameras",
        "random_visibility_mask", "reconstruct", "reprojection_error", "select_kernel", "select_tnh_tau",
        "stack_to_rows",
    ],
    "nldr.paper": ["TABLE1", "TABLE2", "TABLE3", "TABLE4", "paper_frame"],
    "nldr.plotting": ["figure1", "figure3"],
    "nldr.reference": [],
    "nldr.reference.nrsfm": ["tnh_with_camera_refinement_reference"],
    "nldr.reference.regularizer": [
        "finite_difference_pre_image_step", "kernel_mismatch_jacobian", "kernel_mismatch_residuals",
        "minimize_regularized_alternation", "pre_image_step",
    ],
    "nldr.regularizer": [
        "ExactOptions", "LongSolveWarning", "NystroemOptions", "NystroemWarmOptions", "RegularizerResult",
        "minimize_regularized", "reduced_energy",
    ],
    "nldr.result": ["CONVERGED", "INACCURATE", "MAX_ITER", "STATUS_NAMES", "SolverResult"],
    "nldr.robust_kpca": [
        "RobustKernelPCA", "closed_form_rank_penalty", "rank_penalty_energy", "rank_penalty_threshold",
        "shrink_eigenvalues",
    ],
    "nldr.scorecard": ["counts", "score", "to_markdown"],
    "nldr.tables": ["TABLE_COLUMNS", "attach_paper", "to_csv", "to_html", "to_latex", "to_markdown"],
}  # fmt: skip

#: The surface's budget: distinct public objects over all public modules (re-exports count once).
MAX_PUBLIC_NAMES = 120


def public_modules() -> list[str]:
    names = [m.name for m in pkgutil.walk_packages(nldr.__path__, "nldr.")]
    return ["nldr"] + sorted(n for n in names if not any(p.startswith("_") for p in n.split(".")))


def exported(module: str) -> list[str]:
    mod = importlib.import_module(module)
    if not hasattr(mod, "__all__"):  # a package root that exports nothing may omit it
        own = [
            k for k, v in vars(mod).items()
            if not k.startswith("_") and not isinstance(v, types.ModuleType) and k != "annotations"
        ]  # fmt: skip
        assert not own, f"{module} defines public names {own} but no __all__"
        return []
    return sorted(mod.__all__)


def documented() -> tuple[set[str], set[str]]:
    """Modules and objects named by a ``:::`` directive of the API pages."""
    targets = set()
    for page in (REPO / "docs/api").glob("*.md"):
        targets |= set(re.findall(r"^:::\s+([\w.]+)", page.read_text(), flags=re.M))
    modules = {t for t in targets if t in PUBLIC}
    return modules, targets - modules


def test_the_public_modules_and_their_names_are_the_listed_ones():
    assert public_modules() == sorted(PUBLIC)
    changed = {m: exported(m) for m in PUBLIC if exported(m) != sorted(PUBLIC[m])}
    assert not changed, f"__all__ differs from this test's list (update both, and the API pages): {changed}"


def test_every_exported_name_exists_and_is_on_an_api_page():
    modules, objects = documented()
    missing = []
    for module, names in PUBLIC.items():
        mod = importlib.import_module(module)
        for name in names:
            assert hasattr(mod, name), f"{module}.__all__ names {name}, which it does not define"
            if module not in modules and f"{module}.{name}" not in objects:
                missing.append(f"{module}.{name}")
    assert not missing, f"public names no API page renders: {missing}"


def test_the_api_pages_render_no_private_module():
    _, objects = documented()
    private = [t for t in objects if any(p.startswith("_") for p in t.split("."))]
    assert not private, private


def test_the_surface_stays_within_its_budget():
    distinct = {(n, id(getattr(importlib.import_module(m), n))) for m, names in PUBLIC.items() for n in names}
    assert len(distinct) <= MAX_PUBLIC_NAMES, len(distinct)
