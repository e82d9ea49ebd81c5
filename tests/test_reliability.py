"""Reliability: bad configs stop before any job, an interrupted run finishes with the same tables, and
numerical edge cases never let NaN or infinity out of a solver."""

import os
import signal
import subprocess
import time

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from protocol import REPO, SNAKEMAKE, quick_config, quick_results, run_snakemake

from nldr.data_terms import MaskedLeastSquares
from nldr.kernels import rbf_kernel
from nldr.nrsfm import OrthographicReprojection
from nldr.nrsfm._reconstruct import trace_norm_heuristic
from nldr.regularizer import minimize_regularized
from nldr.robust_kpca import closed_form_rank_penalty

QUICK = str(REPO / "config/quick.yaml")
R = quick_results()


# --------------------------------------------------------------------------------------------------
# Bad configuration: rejected by the schema, naming the key, before any job runs


def _set(config, path, value):
    *parents, last = path
    node = config
    for key in parents:
        node = node[key]
    node[last] = value


@pytest.mark.pipeline
@pytest.mark.parametrize(
    "path, value, named",
    [
        (("table1", "gamma"), "wide", "gamma"),  # wrong type
        (("table2", "methods", "Ours", "tau"), -0.1, "tau"),  # negative tau
        (("table2", "methods", "Ours", "rho0"), 0.0, "rho0"),  # rho must be positive
        (("table3", "sequences"), ["drink", "walking"], "sequences"),  # unknown sequence
        (("table2", "p"), [0.1, 1.5], "p"),  # a probability outside (0, 1)
        (("table3", "missing_fraction"), 1.0, "missing_fraction"),
        (("table2", "n_mask"), 3, "n_mask"),  # a typo in a key
        (("scorecard",), [{"table": "table1", "metric": "e", "kind": "close", "doc": "x"}], "kind"),
    ],
)
def test_bad_config_is_rejected_naming_the_key_before_any_job(tmp_path, path, value, named):
    config = quick_config()
    _set(config, path, value)
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(config, sort_keys=False))
    proc = subprocess.run(
        [*SNAKEMAKE, "-d", str(tmp_path), "-c", "1", "--configfile", str(bad)],
        capture_output=True,
        text=True,
        cwd=REPO,
    )
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0
    assert "Error validating config file" in out and named in out, out[-2000:]
    assert not (tmp_path / "results").exists() and not (tmp_path / "resources").exists()


# --------------------------------------------------------------------------------------------------
# Interruption: a run killed inside a heavy job, started again, gives the tables of a clean run


TABLE3 = [f"{R}/tables/table3.csv", "-c", "1", "--configfile", QUICK]


@pytest.fixture(scope="module")
def clean_table3(tmp_path_factory):
    """Table 3's files from an uninterrupted quick run."""
    clean = tmp_path_factory.mktemp("clean")
    proc = subprocess.run([*SNAKEMAKE, "-d", str(clean), *TABLE3], cwd=REPO, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-3000:]
    names = ("table3.csv", "table3.md", "table3.tex")
    return {name: (clean / R / "tables" / name).read_bytes() for name in names}


def _default_sigint():
    """Let Snakemake see Ctrl-C even when the tests run in the background: a shell starts background
    commands with SIGINT ignored, the children inherit that, and Python then never raises
    KeyboardInterrupt (the run went on to its end and the test failed for that reason alone)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _start_and_stop_in_a_job(workdir, sig):
    """Start the Table 3 run, wait until an NRSfM job is inside its solver, send ``sig``, wait."""
    cmd = [*SNAKEMAKE, "-d", str(workdir), *TABLE3]
    proc = subprocess.Popen(
        cmd,
        cwd=REPO,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
        preexec_fn=_default_sigint,
    )
    logs = workdir / R / "logs/run/table3"
    started = {p.name for p in logs.glob("*.log")} if logs.is_dir() else set()
    deadline = time.monotonic() + 120
    try:
        while time.monotonic() < deadline and not any(
            "e3d=" in p.read_text() for p in logs.glob("*.log") if p.is_file() and p.name not in started
        ):
            assert proc.poll() is None, "the run ended before it could be interrupted"
            time.sleep(0.2)
        assert time.monotonic() < deadline, "no table3 job started within 2 minutes"
    finally:
        if sig == signal.SIGKILL:
            os.killpg(proc.pid, sig)  # the machine dies: Snakemake and its jobs at once
        else:
            os.kill(proc.pid, sig)  # Ctrl-C or a scheduler's TERM: Snakemake itself is told
        proc.wait(timeout=120)
    return cmd


def _assert_cut_short(workdir, *, strictly=True):
    """No temporary file is left behind; with ``strictly``, the run really was cut short."""
    partial = [p for p in (workdir / R).rglob("*") if p.is_file() and p.name.startswith(".")]
    assert not partial, partial
    if strictly:
        done = {p.name for p in (workdir / R / "runs/table3").glob("*.csv")}
        assert len(done) < 2 * len(quick_config()["table3"]["sequences"])
        assert not (workdir / R / "tables/table3.csv").exists()


@pytest.mark.pipeline
def test_run_killed_in_a_heavy_job_finishes_with_the_same_table(tmp_path, clean_table3):
    interrupted = tmp_path / "interrupted"
    cmd = _start_and_stop_in_a_job(interrupted, signal.SIGKILL)
    _assert_cut_short(interrupted)
    # SIGKILL leaves Snakemake's lock behind: the next run says so and names the fix
    locked = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True)
    assert locked.returncode != 0 and "--unlock" in locked.stdout + locked.stderr
    unlock = subprocess.run([*SNAKEMAKE, "-d", str(interrupted), "--unlock"], cwd=REPO, capture_output=True)
    assert unlock.returncode == 0
    again = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True)
    assert again.returncode == 0, again.stderr[-3000:]
    for name, clean in clean_table3.items():
        assert (interrupted / R / "tables" / name).read_bytes() == clean, name


@pytest.mark.pipeline
def test_run_interrupted_by_sigint_then_sigterm_finishes_with_the_same_table(tmp_path, clean_table3):
    """Ctrl-C, then a scheduler's SIGTERM in the resumed run: Snakemake stops its jobs, removes their
    incomplete outputs and releases its lock, so the next plain run finishes the table."""
    interrupted = tmp_path / "interrupted"
    cmd = _start_and_stop_in_a_job(interrupted, signal.SIGINT)
    _assert_cut_short(interrupted)
    _start_and_stop_in_a_job(interrupted, signal.SIGTERM)
    # the resumed run has few jobs left, each a few seconds: on a quiet machine it may finish a job
    # between the signal being decided and sent, so only "nothing half-written" is required here
    _assert_cut_short(interrupted, strictly=False)
    again = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True)
    assert again.returncode == 0, again.stderr[-3000:]  # no --unlock needed
    for name, clean in clean_table3.items():
        assert (interrupted / R / "tables" / name).read_bytes() == clean, name


# --------------------------------------------------------------------------------------------------
# Numerical edge cases: no NaN or infinity leaves a solver


def _finite(*arrays):
    return all(np.all(np.isfinite(a)) for a in arrays)


@settings(max_examples=25, deadline=None)
@given(
    n_unique=st.integers(2, 6),
    repeats=st.integers(2, 4),
    log_gamma=st.floats(-6, 4),
    tau=st.floats(1e-3, 10.0),
    seed=st.integers(0, 2**16),
)
def test_duplicate_points_and_extreme_widths_stay_finite(n_unique, repeats, log_gamma, tau, seed):
    """Repeated samples (zero distances, a rank-deficient kernel) with gamma from 1e-6 to 1e4."""
    rng = np.random.default_rng(seed)
    W = np.repeat(rng.standard_normal((n_unique, 3)), repeats, axis=0)
    mask = rng.random(W.shape) > 0.3
    mask[0] = True  # every column observed somewhere
    res = minimize_regularized(
        MaskedLeastSquares(W, mask), np.where(mask, W, 0.0), gamma=10.0**log_gamma, tau=tau, rho_max=100.0
    )
    assert _finite(res.x, res.C, res.energy_history)
    assert isinstance(res.success, bool) and res.message


@settings(max_examples=40, deadline=None)
@given(lam=st.floats(1e-6, 1e3), ratio=st.floats(1e-3, 1e3), seed=st.integers(0, 2**16))
def test_eigenvalues_at_the_cubic_threshold_are_handled(lam, ratio, seed):
    """An eigenvalue placed exactly where l* jumps from 0 to a positive root (both candidates tie).

    With rho = 1, phi(l) = (lam - l^2)^2 / 2 + tau l. A positive stationary point satisfies
    l^3 - lam l + tau / 2 = 0; it ties with l = 0 when l^3 - 2 lam l + 2 tau = 0. Together:
    l = 3 tau / (2 lam) and tau^2 = 8 lam^3 / 27, i.e. tau = (2 lam / 3)^(3/2).
    """
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.standard_normal((5, 5)))
    spectrum = np.array([lam, lam * ratio, 0.0, lam / 2, 2 * lam])
    K = (Q * spectrum) @ Q.T
    K = (K + K.T) / 2
    tau = (2.0 * lam / 3.0) ** 1.5
    C = closed_form_rank_penalty(K, tau=tau, rho=1.0)
    assert _finite(C)
    energy = tau * np.linalg.svd(C, compute_uv=False).sum() + 0.5 * np.sum((K - C.T @ C) ** 2)
    # brute force per eigenvalue: l = 0 or any l on a fine grid up to sqrt(2 max(lam_i, 0))
    best = 0.0
    for s in spectrum:
        grid = np.linspace(0.0, np.sqrt(2 * max(s, 0.0)) + 1e-12, 20001)
        best += np.min((s - grid**2) ** 2 / 2 + tau * grid)
    assert energy <= best * (1 + 1e-9) + 1e-12


def test_rank_deficient_and_nearly_singular_kernels():
    rng = np.random.default_rng(0)
    X = rng.standard_normal((30, 2))
    for K in (
        np.ones((30, 30)),
        rbf_kernel(X, gamma=1e-9),
        rbf_kernel(np.repeat(X[:5], 6, axis=0), gamma=0.5),
    ):
        for tau in (1e-6, 1.0, 1e3):
            assert _finite(closed_form_rank_penalty(K, tau=tau, rho=1.0))


def test_all_missing_rows_are_filled_finitely():
    rng = np.random.default_rng(1)
    t = rng.uniform(0, 2 * np.pi, 40)
    W = np.c_[np.cos(t), np.sin(t), t / 3]
    mask = np.ones(W.shape, dtype=bool)
    mask[[3, 17, 29]] = False  # three rows with no observed entry
    res = minimize_regularized(MaskedLeastSquares(W, mask), np.where(mask, W, 0.0), gamma=1.0, tau=0.1)
    assert _finite(res.x) and res.success


def test_a_frame_with_no_observed_point_stays_finite():
    rng = np.random.default_rng(2)
    F, P = 12, 8
    basis = rng.standard_normal((2, 3 * P))
    X = rng.standard_normal((F, 2)) @ basis + rng.standard_normal(3 * P)
    Q = np.linalg.qr(rng.standard_normal((F, 3, 3)))[0]
    R = Q[:, :2, :]
    W2d = np.einsum("fck,fkp->fcp", R, X.reshape(F, 3, P)).reshape(F, 2 * P)
    mask = rng.random((F, P)) > 0.3
    mask[5] = False  # frame 5 shows nothing
    with pytest.warns(UserWarning, match=r"frames \[5\] have no visible point"):
        term = OrthographicReprojection(W2d, mask, R)
    tnh = trace_norm_heuristic(W2d, mask, R, tau=1e-2, method="cvxpy")
    res = minimize_regularized(term, tnh.x, gamma=0.1, tau=1e-4, rho0=1e-3, rho_max=10.0)
    assert _finite(tnh.x, res.x)


@pytest.mark.pipeline
def test_corrupt_mirror_stops_the_pipeline_before_results(tmp_path, data_dir):
    """A mirror file with one byte flipped: the run fails naming the file and its sha256, and nothing
    is written under results/ (nor a bad copy under resources/)."""
    from nldr.datasets import FILES, fetch

    mirror = tmp_path / "mirror"
    for rel in ("oil/DataTrn.txt", "oil/DataTrnLbls.txt"):
        (mirror / rel).parent.mkdir(parents=True, exist_ok=True)
        (mirror / rel).write_bytes(fetch(rel, data_dir).read_bytes())
    target = mirror / "oil/DataTrn.txt"
    data = bytearray(target.read_bytes())
    data[200] ^= 0x01
    target.write_bytes(bytes(data))
    work = tmp_path / "work"
    env = {**os.environ, "NLDR_DATA_MIRROR": str(mirror)}
    proc = subprocess.run(
        [*SNAKEMAKE, "-d", str(work), "-c", "1", f"{R}/tables/table2.csv", "--configfile", QUICK],
        cwd=REPO,
        capture_output=True,
        text=True,
        env=env,
    )
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0
    assert "oil/DataTrn.txt" in out and FILES["oil/DataTrn.txt"].sha256 in out and "NLDR_DATA_MIRROR" in out
    written = [p for p in (work / "results").rglob("*") if p.is_file() and "logs" not in p.parts]
    assert not written, written  # only the failed fetch's log
    assert not (work / "resources/oil/DataTrn.txt").exists()


@pytest.mark.pipeline
def test_data_corrupted_after_a_good_run_stops_the_rerun_with_every_result_intact(tmp_path):
    """A good quick Table 2 run, then an HTML page written over its input: the rerun fails before
    any job, naming the file, and every result file is still there with the same bytes."""
    from nldr.datasets import FILES

    work = tmp_path / "work"
    # quick Table 2 at its first p on one mask (a smaller overlay: the same rules and files, one job)
    small = tmp_path / "table2_small.yaml"
    small.write_text(yaml.safe_dump({"table2": {"p": quick_config()["table2"]["p"][:1], "n_masks": 1}}))
    configs = ["--configfile", QUICK, str(small)]
    proc = run_snakemake(work, f"{R}/tables/table2.csv", "-c", "2", *configs)
    assert proc.returncode == 0, proc.stderr[-3000:]

    def results():
        return {
            p.relative_to(work): p.read_bytes()
            for p in (work / "results").rglob("*")
            if p.is_file() and "logs" not in p.parts
        }

    before = results()
    assert any(p.suffix == ".csv" and "runs" in p.parts for p in before)
    data = work / "resources/oil/DataTrn.txt"
    data.write_text("<!DOCTYPE html><html><body>rate limited</body></html>\n")
    proc = run_snakemake(work, f"{R}/tables/table2.csv", "-c", "2", *configs)
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0
    assert "oil/DataTrn.txt" in out and FILES["oil/DataTrn.txt"].sha256 in out
    assert "Traceback" not in out
    assert results() == before


# --------------------------------------------------------------------------------------------------
# Library edge cases: a clear ValueError or a warning, never a silent non-finite or empty result


def test_huge_data_is_refused_before_the_solver():
    rng = np.random.default_rng(0)
    W = rng.standard_normal((20, 4)) * 1e200
    with pytest.raises(ValueError, match="W has entries up to .* Rescale W"):
        MaskedLeastSquares(W, np.ones_like(W, dtype=bool))
    with pytest.raises(ValueError, match="overflow float64.*rescale"):
        rbf_kernel(W, 1.0)


def test_center_kernel_rejects_non_finite_and_non_square():
    from nldr.kernels import center_kernel

    K = np.eye(4)
    K[1, 2] = np.nan
    with pytest.raises(ValueError, match="K contains NaN"):
        center_kernel(K)
    with pytest.raises(ValueError, match="square"):
        center_kernel(np.ones((3, 4)))


def test_reprojection_rejects_transposed_shapes_and_empty_visibility():
    rng = np.random.default_rng(1)
    F, P = 6, 3  # 3P = 9 != F, so X.T has the same size but not the same shape
    W2d, R = rng.standard_normal((F, 2 * P)), np.tile(np.eye(3)[:2], (F, 1, 1))
    term = OrthographicReprojection(W2d, None, R)
    X = rng.standard_normal((F, 3 * P))
    with pytest.raises(ValueError, match=r"X must have shape \(F, 3P\)"):
        term.gradient(X.T.copy().reshape(3 * P, F))
    with pytest.raises(ValueError, match="no visible point"):
        OrthographicReprojection(W2d, np.zeros((F, P), dtype=bool), R)
    mask = np.ones((F, P), dtype=bool)
    mask[2] = False
    with pytest.warns(UserWarning, match=r"frames \[2\] have no visible point"):
        OrthographicReprojection(W2d, mask, R)


def test_robust_kpca_warns_when_tau_removes_every_component():
    from nldr.robust_kpca import RobustKernelPCA

    X = np.random.default_rng(2).standard_normal((15, 3))
    with pytest.warns(UserWarning, match="removes every component"):
        Z = RobustKernelPCA(gamma=0.5, tau=1e6, rho=1.0).fit_transform(X)
    assert Z.shape == (15, 0)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_observed_data_is_refused_by_every_data_term(bad):
    """NaN is allowed where unobserved (it is ignored) and refused where observed, naming the input."""
    rng = np.random.default_rng(3)
    W, mask = rng.standard_normal((6, 4)), np.ones((6, 4), dtype=bool)
    mask[0, 0] = False
    W[0, 0] = np.nan
    MaskedLeastSquares(W, mask)  # unobserved NaN: fine
    W[1, 2] = bad
    with pytest.raises(ValueError, match="W has NaN or infinite values at observed entries"):
        MaskedLeastSquares(W, mask)
    W2d, R = rng.standard_normal((4, 6)), np.tile(np.eye(3)[:2], (4, 1, 1))
    W2d[2, 1] = bad
    with pytest.raises(ValueError, match="W2d has NaN or infinite values at observed entries"):
        OrthographicReprojection(W2d, None, R)
