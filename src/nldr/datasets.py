"""Data sets of the paper: three-phase oil flow and the CMU mocap NRSfM sequences.

Every file is pinned by URL (a fixed commit of a public repository) and sha256: :data:`FILES` is the
registry, :func:`registry` gives it in pooch's form. A file is looked up, in order, in the data
directory (``data_dir`` argument, else ``$NLDR_DATA_DIR``, else the user's cache folder of the
operating system, ``pooch.os_cache("nldr")``, e.g. ``~/.cache/nldr`` on Linux; the pipeline passes
its config's ``data.dir``, ``resources/``); when missing there it is copied from the local mirror
folder ``$NLDR_DATA_MIRROR`` (same layout as the data directory, e.g.
``$NLDR_DATA_MIRROR/oil/DataTrn.txt``) or, without a mirror, downloaded by pooch (with retries). A
file is written to a temporary name and renamed only after its sha256 matched, so a partial or wrong
file is never left behind. Loading verifies the hash again and checks shapes.

This is the one module of the library that touches files: it is the edge where data enter.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = [
    "DataError",
    "FILES",
    "OIL_SPLITS",
    "MOCAP_SEQUENCES",
    "default_data_dir",
    "registry",
    "fetch",
    "verify_present",
    "load_oil",
    "load_oil_rows",
    "MocapSequence",
    "load_mocap",
]

_OIL_URL = (
    "https://raw.githubusercontent.com/lawrennd/datasets_mirror/"
    "2eb6dce7501464457465facc7ef9334250efe4b4/three_phase_oil_flow/{}"
)
_MOCAP_URL = (
    "https://raw.githubusercontent.com/JingweiSong/NRSfM_uncertainty/"
    "8cab4ca322007419f5a35f48c2e968a75d8b7b3d/data/{}"
)


class DataError(RuntimeError):
    """A data file is missing, corrupt or malformed; the message names the file and the fix."""


@dataclass(frozen=True)
class DataFile:
    """A pinned data file: path relative to the data directory, source URL, sha256."""

    relpath: str
    url: str
    sha256: str


FILES: dict[str, DataFile] = {
    f"oil/{name}": DataFile(f"oil/{name}", _OIL_URL.format(name), digest)
    for name, digest in [
        ("DataTrn.txt", "ff1aeeceb204de936990bc22cc9d0e4ca7094e993a6d723509c60be0b0f2a136"),
        ("DataTrnLbls.txt", "15e5ce14ca8054ca34b984b8da7d8ffeff682f86af2772911e9deccdd4d438c0"),
        ("DataTst.txt", "f287fda27a2b6b9e93de22ebed7229d1c57bd7e3154d6291b66f99521816e466"),
        ("DataTstLbls.txt", "411dcc8d566cf1f9a40bdb16d9d0e2ddf934b534a840e508efd4be4ce5827d2f"),
        ("DataVdn.txt", "2faab71737820af032f8d418669dcda5342296cba53116c43fb9e76b45f51710"),
        ("DataVdnLbls.txt", "b6073b1f0719451cec67cddad533decf6448aa026482f872e211e848007ebbe8"),
    ]
} | {
    f"nrsfm/{name}.mat": DataFile(f"nrsfm/{name}.mat", _MOCAP_URL.format(f"{name}.mat"), digest)
    for name, digest in [
        ("drink", "4cb68c475902e927a1471f4a9f7517e29b7bd30c6e403f4a64fb6c84e13d83a7"),
        ("pickup", "edbe644459d5f33947ec5e922abfd5209a10e493b85b14bf4d68e24986a54c56"),
        ("yoga", "fb1df52774ee71f2f5ad51a3357b6741b601705409ff4655a22ee3d20558b5a0"),
        ("stretch", "bf86e3937bc5c6875519728f7e9f7f8b51c2eb6d0059035337a5f0c6e5c2e3ac"),
        ("dance", "3524d4e29c4ab17cac958549376f937d0418a2997e15d190d2216292fa081aab"),
    ]
}

OIL_SPLITS = {"train": "Trn", "test": "Tst", "validation": "Vdn"}
#: Rows of each oil-flow split, and of the three together.
OIL_SPLIT_ROWS = 1000
OIL_ROWS = 3 * OIL_SPLIT_ROWS
MOCAP_SEQUENCES = ("drink", "pickup", "yoga", "stretch", "dance")

_MIRROR_HINT = (
    "Set NLDR_DATA_MIRROR to a folder holding the files in the same layout "
    "(e.g. NLDR_DATA_MIRROR=../shared/data), or allow network access to download them."
)


def default_data_dir() -> Path:
    """``$NLDR_DATA_DIR`` if set, else the operating system's cache folder for nldr
    (``pooch.os_cache("nldr")``: ``~/.cache/nldr`` on Linux, ``~/Library/Caches/nldr`` on macOS)."""
    if os.environ.get("NLDR_DATA_DIR"):
        return Path(os.environ["NLDR_DATA_DIR"])
    import pooch

    return Path(pooch.os_cache("nldr"))


def registry() -> dict[str, str]:
    """:data:`FILES` as a pooch registry: relative path -> ``"sha256:<hex>"``."""
    return {rel: f"sha256:{spec.sha256}" for rel, spec in FILES.items()}


#: Download attempts after the first failed one (pooch's ``retry_if_failed``).
DOWNLOAD_RETRIES = 2


def _download(spec: DataFile, data_dir: Path) -> None:
    """Download ``spec`` into ``data_dir/spec.relpath`` with pooch: the hash checked before the file
    takes its name, retries on a failed attempt; DataError naming the file and the fix otherwise."""
    import pooch
    import requests

    store = pooch.create(
        path=data_dir,
        base_url="",
        registry={spec.relpath: f"sha256:{spec.sha256}"},
        urls={spec.relpath: spec.url},
        retry_if_failed=DOWNLOAD_RETRIES,
    )
    try:
        store.fetch(spec.relpath, downloader=pooch.HTTPDownloader(timeout=60, progressbar=False))
    except (OSError, requests.RequestException, ValueError) as exc:  # ValueError: pooch's hash check
        raise DataError(f"{spec.relpath}: download from {spec.url} failed ({exc}). {_MIRROR_HINT}") from None


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _spec(relpath: str) -> DataFile:
    try:
        return FILES[relpath]
    except KeyError:
        raise ValueError(f"unknown data file {relpath!r}; known: {sorted(FILES)}") from None


def verify(path, relpath: str, *, source=None) -> Path:
    """Check that ``path`` holds the pinned content of ``relpath``; raise DataError otherwise.

    ``source`` names where the bytes came from (a mirror file or a URL) when ``path`` is a temporary
    copy: the message then names the source and says to fix it, not the copy (which is deleted).
    """
    spec, path = _spec(relpath), Path(path)
    if not path.is_file():
        raise DataError(f"{relpath}: file {path} does not exist. {_MIRROR_HINT}")
    try:
        digest = _sha256(path)
    except OSError as exc:
        raise DataError(f"{relpath}: cannot read {path} ({exc.strerror or exc}).") from None
    if digest != spec.sha256:
        where = path if source is None else source
        fix = (
            f"Delete it and fetch again from {spec.url} or a mirror."
            if source is None
            else f"Replace {source} with the pinned file (source {spec.url})."
        )
        raise DataError(
            f"{relpath}: {where} has sha256 {digest}, expected {spec.sha256} "
            f"(size {path.stat().st_size} bytes; a truncated download, an HTML error page or a "
            f"different version gives this). {fix} {_MIRROR_HINT}"
        )
    return path


def verify_present(data_dir) -> list[Path]:
    """Verify every pinned file already present under ``data_dir``; return their paths.

    The pipeline calls this before it schedules any job, so a data file changed or corrupted after a
    good run stops the run at once: Snakemake would otherwise rerun every job downstream of the
    changed file, deleting their (good) outputs first, and each would then fail on the hash.

    Raises
    ------
    DataError
        Naming every present file whose sha256 differs from the pinned one, or that cannot be read.
    """
    data_dir, checked, problems = Path(data_dir), [], []
    for relpath in FILES:
        path = data_dir / relpath
        if not path.exists():
            continue
        try:
            checked.append(verify(path, relpath))
        except DataError as exc:
            problems.append(str(exc))
    if problems:
        raise DataError("\n".join(problems))
    return checked


def fetch(relpath: str, data_dir=None, *, mirror=None) -> Path:
    """Make ``data_dir/relpath`` present and verified; return its path.

    Parameters
    ----------
    relpath : str
        A key of :data:`FILES`, e.g. ``"oil/DataTrn.txt"`` or ``"nrsfm/drink.mat"``.
    data_dir : path, optional
        Destination directory (default :func:`default_data_dir`).
    mirror : path, optional
        Local mirror folder; defaults to ``$NLDR_DATA_MIRROR``. When set, nothing is downloaded;
        otherwise pooch downloads the file from its pinned URL (:data:`DOWNLOAD_RETRIES` retries).

    Raises
    ------
    DataError
        When the file cannot be obtained or its sha256 differs from the pinned one.
    """
    spec = _spec(relpath)
    root = Path(default_data_dir() if data_dir is None else data_dir)
    dest = root / spec.relpath
    if dest.is_file():
        return verify(dest, relpath)
    mirror = os.environ.get("NLDR_DATA_MIRROR") if mirror is None else mirror
    source = Path(mirror) / spec.relpath if mirror else None
    try:
        dest.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp_name = tempfile.mkstemp(dir=dest.parent, prefix=f".{dest.name}.", suffix=".part")
    except OSError as exc:
        return _unwritable(relpath, root, dest.parent, exc, source, data_dir is None)
    if not mirror:
        os.close(fd)
        Path(tmp_name).unlink(missing_ok=True)
        _download(spec, root)
        return verify(dest, relpath, source=spec.url)
    tmp = Path(tmp_name)
    try:
        with os.fdopen(fd, "wb") as out:
            if not source.is_file():
                raise DataError(
                    f"{relpath}: not found in the mirror NLDR_DATA_MIRROR={mirror} (looked for "
                    f"{source}). Put the file there (sha256 {spec.sha256}, source {spec.url})."
                )
            try:
                with open(source, "rb") as src:
                    shutil.copyfileobj(src, out)
            except OSError as exc:
                raise DataError(
                    f"{relpath}: cannot read the mirror file {source} ({exc.strerror or exc})."
                ) from None
        verify(tmp, relpath, source=source)
        os.chmod(tmp, 0o644)  # mkstemp creates 0600
        os.replace(tmp, dest)
    finally:
        tmp.unlink(missing_ok=True)
    return dest


def _unwritable(relpath, root, folder, exc, source, from_env) -> Path:
    """``fetch`` cannot write into the data directory: use a readable, verified mirror copy in place
    (with a warning), else a DataError naming the folder and the fix."""
    where = "NLDR_DATA_DIR" if from_env and os.environ.get("NLDR_DATA_DIR") else "the data directory"
    problem = (
        f"{relpath}: cannot write into {where} {root} ({type(exc).__name__}: {exc.strerror or exc}"
        f"{'; it is a file, not a folder' if root.is_file() else ''})"
    )
    if source is not None and source.is_file():
        path = verify(source, relpath)
        warnings.warn(
            f"{problem}; reading the mirror copy {path} in place instead. Point NLDR_DATA_DIR (or "
            "data_dir) at a writable folder to keep a copy.",
            UserWarning,
            stacklevel=3,
        )
        return path
    hint = (
        f" The mirror has no {source} either." if source is not None else f" {_MIRROR_HINT}"
    )
    raise DataError(
        f"{problem}. Point NLDR_DATA_DIR (or data_dir) at a writable folder, or unset it to use the "
        f"cache folder.{hint}"
    )


def load_oil(split: str = "train", data_dir=None) -> tuple[np.ndarray, np.ndarray]:
    """Three-phase oil flow data (Bishop & James 1993), 1000 samples per split.

    Parameters
    ----------
    split : {"train", "test", "validation"}
    data_dir : path, optional

    Returns
    -------
    X : float array, shape (1000, 12)
        Dual-energy gamma densitometry readings (dimensionless).
    y : int array, shape (1000,)
        Flow regime, the index of the one-hot label column: 0, 1 or 2.
    """
    if split not in OIL_SPLITS:
        raise ValueError(f"split must be one of {sorted(OIL_SPLITS)}; got {split!r}")
    tag = OIL_SPLITS[split]
    arrays = []
    for relpath in (f"oil/Data{tag}.txt", f"oil/Data{tag}Lbls.txt"):
        path = fetch(relpath, data_dir)
        try:
            arrays.append(np.loadtxt(path, ndmin=2))
        except ValueError as exc:
            raise DataError(
                f"{relpath}: {path} is not a whitespace-separated numeric table ({exc})"
            ) from None
    X, onehot = arrays
    if X.shape[1] != 12 or onehot.shape != (X.shape[0], 3):
        raise DataError(
            f"oil/{tag}: expected (n, 12) data and (n, 3) one-hot labels; got {X.shape} and {onehot.shape}"
        )
    if not np.allclose(onehot.sum(axis=1), 1.0):
        raise DataError(f"oil/Data{tag}Lbls.txt: rows must be one-hot (sum to 1)")
    return X, onehot.argmax(axis=1).astype(np.int64)


def load_oil_rows(n: int, data_dir=None) -> np.ndarray:
    """The first ``n`` oil-flow rows of the training, then validation, then test split.

    Returns X, float array of shape (n, 12); ValueError unless n is an integer in 1..3000 (checked
    before any file is read or fetched). Only the splits the first n rows need are loaded.
    """
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or not 0 < n <= OIL_ROWS:
        raise ValueError(f"n must be an integer in 1..{OIL_ROWS} (rows of the three splits); got {n!r}")
    splits = ("train", "validation", "test")[: -(-int(n) // OIL_SPLIT_ROWS)]
    X = np.vstack([load_oil(split, data_dir)[0] for split in splits])
    return X[:n]


@dataclass(frozen=True)
class MocapSequence:
    """A CMU mocap NRSfM sequence (Akhter et al. 2009), in the original (unnormalised) units.

    Attributes
    ----------
    name : str
    W : array, shape (2F, P)
        Orthographic image tracks; rows 2f, 2f+1 are x and y of frame f (zero mean per row).
    S : array, shape (3F, P)
        Ground-truth 3D shapes; rows 3f..3f+2 are X, Y, Z of frame f (zero mean per frame).
    R : array, shape (F, 2, 3) or None
        Ground-truth orthographic cameras, W_f = R_f S_f (None for dance, which has none).
    bones : int array, shape (B, 2)
        Skeleton edges as 0-based point indices, for drawing (empty for dance).
    scale : float
        The factor the stored copy had been divided by (S and W here are already multiplied back).
    """

    name: str
    W: np.ndarray
    S: np.ndarray
    R: np.ndarray | None
    bones: np.ndarray
    scale: float

    @property
    def n_frames(self) -> int:
        return self.S.shape[0] // 3

    @property
    def n_points(self) -> int:
        return self.S.shape[1]

    def subsample(self, step: int = 10, start: int = 0) -> MocapSequence:
        """Every ``step``-th frame from ``start`` (the paper uses step 10 from the first frame)."""
        if step < 1 or not 0 <= start < self.n_frames:
            raise ValueError(f"need step >= 1 and 0 <= start < {self.n_frames}; got {step}, {start}")
        frames = np.arange(start, self.n_frames, step)
        rows2 = (2 * frames[:, None] + np.arange(2)).ravel()
        rows3 = (3 * frames[:, None] + np.arange(3)).ravel()
        R = None if self.R is None else self.R[frames]
        return MocapSequence(self.name, self.W[rows2], self.S[rows3], R, self.bones, self.scale)


def load_mocap(name: str, data_dir=None) -> MocapSequence:
    """Load a CMU mocap NRSfM sequence: drink, pickup, yoga, stretch or dance.

    The available copies were divided by ``scale = max|S|``; S and W are multiplied back here, so
    the paper's regularisation strengths (tau) apply as published. See PROVENANCE in the docs.
    """
    if name not in MOCAP_SEQUENCES:
        raise ValueError(f"name must be one of {MOCAP_SEQUENCES}; got {name!r}")
    relpath = f"nrsfm/{name}.mat"
    path = fetch(relpath, data_dir)
    from scipy.io import loadmat

    try:
        mat = loadmat(path)
    except Exception as exc:  # scipy raises several types for a malformed file
        raise DataError(f"{relpath}: {path} is not a readable MATLAB file ({exc})") from None
    missing = [key for key in ("W", "S", "scale") if key not in mat]
    if missing:
        raise DataError(f"{relpath}: variables {missing} missing from {path}")
    scale = float(np.squeeze(mat["scale"]))
    W = np.asarray(mat["W"], dtype=np.float64) * scale
    S = np.asarray(mat["S"], dtype=np.float64) * scale
    if S.shape[0] % 3 or W.shape != (2 * (S.shape[0] // 3), S.shape[1]):
        raise DataError(f"{relpath}: expected W (2F, P) and S (3F, P); got {W.shape} and {S.shape}")
    F = S.shape[0] // 3
    R = None
    if "Rs" in mat:
        Rs = np.asarray(mat["Rs"], dtype=np.float64)
        if Rs.shape != (2 * F, 3):
            raise DataError(f"{relpath}: expected Rs of shape {(2 * F, 3)}; got {Rs.shape}")
        R = Rs.reshape(F, 2, 3)
    if "list" in mat:  # 1-based MATLAB indices
        bones = np.asarray(mat["list"], dtype=np.int64).reshape(-1, 2) - 1
    else:
        bones = np.zeros((0, 2), dtype=np.int64)
    return MocapSequence(name, W, S, R, bones, scale)
