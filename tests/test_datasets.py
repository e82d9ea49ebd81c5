"""Data layer: real files via the mirror (fail, not skip, when missing) and every corruption case."""

import os
import shutil

import numpy as np
import pooch
import pytest
import requests

from nldr import datasets
from nldr.datasets import FILES, DataError, fetch, load_mocap, load_oil

MIRROR = os.environ.get("NLDR_DATA_MIRROR")


def test_oil_splits_have_the_documented_shapes(data_dir):
    counts = {"train": [343, 316, 341], "test": [324, 363, 313], "validation": [334, 325, 341]}
    for split, expected in counts.items():
        X, y = load_oil(split, data_dir)
        assert X.shape == (1000, 12) and X.dtype == np.float64
        assert y.dtype.kind == "i" and set(np.unique(y)) == {0, 1, 2}
        assert np.bincount(y).tolist() == expected


@pytest.mark.parametrize(
    ("name", "frames"), [("drink", 1102), ("pickup", 357), ("yoga", 307), ("stretch", 370)]
)
def test_mocap_is_in_original_units_and_projects_exactly(data_dir, name, frames):
    seq = load_mocap(name, data_dir)
    assert seq.S.shape == (3 * frames, 41) and seq.W.shape == (2 * frames, 41)
    assert seq.R.shape == (frames, 2, 3)
    # the stored copy was divided by scale = max|S|, so after un-scaling max|S| equals scale
    assert np.abs(seq.S).max() == pytest.approx(seq.scale, rel=1e-12)
    shapes = seq.S.reshape(frames, 3, 41)
    np.testing.assert_allclose(np.einsum("fij,fjp->fip", seq.R, shapes).reshape(-1, 41), seq.W, atol=1e-12)
    np.testing.assert_allclose(
        np.einsum("fij,fkj->fik", seq.R, seq.R), np.broadcast_to(np.eye(2), (frames, 2, 2)), atol=1e-12
    )
    assert seq.bones.min() >= 0 and seq.bones.max() < 41
    sub = seq.subsample(10)
    assert sub.n_frames == len(range(0, frames, 10))
    np.testing.assert_array_equal(sub.S[3:6], seq.S[30:33])
    np.testing.assert_array_equal(sub.R[1], seq.R[10])


def test_dance_has_no_cameras(data_dir):
    seq = load_mocap("dance", data_dir)
    assert seq.R is None and seq.S.shape == (792, 75) and seq.bones.shape == (0, 2)


@pytest.fixture
def mirror_copy(tmp_path, data_dir):
    """A private mirror holding a verified copy of the oil training file."""
    src = fetch("oil/DataTrn.txt", data_dir)
    mirror = tmp_path / "mirror"
    (mirror / "oil").mkdir(parents=True)
    shutil.copy(src, mirror / "oil" / "DataTrn.txt")
    return mirror


def _no_leftovers(folder):
    return not any(p.name.endswith(".part") for p in folder.rglob("*"))


def test_fetch_copies_from_mirror_and_verifies(tmp_path, mirror_copy):
    dest = tmp_path / "res"
    path = fetch("oil/DataTrn.txt", dest, mirror=mirror_copy)
    assert path == dest / "oil" / "DataTrn.txt" and path.is_file()


@pytest.mark.parametrize(
    "corrupt",
    [
        lambda b: b[:100] + bytes([b[100] ^ 0x01]) + b[101:],  # one byte flipped
        lambda b: b[: len(b) // 2],  # truncated
        lambda b: b"<!DOCTYPE html><html><body>404: Not Found</body></html>",  # an error page
    ],
    ids=["flipped", "truncated", "html"],
)
def test_corrupt_mirror_file_gives_a_clear_error_and_leaves_nothing(tmp_path, mirror_copy, corrupt):
    target = mirror_copy / "oil" / "DataTrn.txt"
    target.write_bytes(corrupt(target.read_bytes()))
    dest = tmp_path / "res"
    with pytest.raises(DataError) as info:
        fetch("oil/DataTrn.txt", dest, mirror=mirror_copy)
    message = str(info.value)
    assert "oil/DataTrn.txt" in message and FILES["oil/DataTrn.txt"].sha256 in message
    assert "NLDR_DATA_MIRROR" in message
    assert not (dest / "oil" / "DataTrn.txt").exists() and _no_leftovers(dest)


def test_corrupt_file_in_data_dir_is_detected_on_load(tmp_path, mirror_copy):
    dest = tmp_path / "res"
    path = fetch("oil/DataTrn.txt", dest, mirror=mirror_copy)
    path.write_bytes(path.read_bytes()[:-10])
    with pytest.raises(DataError, match="expected " + FILES["oil/DataTrn.txt"].sha256):
        datasets.verify(path, "oil/DataTrn.txt")


def test_missing_from_mirror_names_the_file_and_the_fix(tmp_path):
    with pytest.raises(DataError, match=r"nrsfm/yoga\.mat.*not found in the mirror"):
        fetch("nrsfm/yoga.mat", tmp_path / "res", mirror=tmp_path / "empty")
    assert _no_leftovers(tmp_path)


def test_no_mirror_and_no_network_fails_clearly(tmp_path, monkeypatch):
    monkeypatch.delenv("NLDR_DATA_MIRROR", raising=False)

    attempts = []

    def offline(*args, **kwargs):
        attempts.append(args[0] if args else kwargs.get("url"))
        raise requests.ConnectionError("network is unreachable")

    monkeypatch.setattr(requests, "get", offline)  # what pooch's HTTP downloader calls
    with pytest.raises(
        DataError, match=r"oil/DataTst\.txt: download from https://.* failed.*NLDR_DATA_MIRROR"
    ):
        fetch("oil/DataTst.txt", tmp_path / "res")
    assert not (tmp_path / "res" / "oil" / "DataTst.txt").exists() and _no_leftovers(tmp_path)
    assert attempts == [FILES["oil/DataTst.txt"].url] * (1 + datasets.DOWNLOAD_RETRIES)  # retried


def test_unknown_names_are_rejected():
    with pytest.raises(ValueError, match="split"):
        load_oil("training")
    with pytest.raises(ValueError, match="name"):
        load_mocap("walk")
    with pytest.raises(ValueError, match="unknown data file"):
        fetch("oil/other.txt")


def test_fetch_reverifies_a_file_already_in_place(tmp_path, mirror_copy):
    """A file already in the data folder is not trusted: fetch checks its hash again."""
    dest = tmp_path / "res"
    path = fetch("oil/DataTrn.txt", dest, mirror=mirror_copy)
    path.write_bytes(path.read_bytes()[:-10])
    with pytest.raises(DataError, match="expected " + FILES["oil/DataTrn.txt"].sha256):
        fetch("oil/DataTrn.txt", dest, mirror=mirror_copy)


def test_truncated_mirror_file_is_named_not_the_temporary_copy(tmp_path, mirror_copy):
    source = mirror_copy / "oil" / "DataTrn.txt"
    source.write_bytes(source.read_bytes()[:1000])
    with pytest.raises(DataError) as info:
        fetch("oil/DataTrn.txt", tmp_path / "res", mirror=mirror_copy)
    message = str(info.value)
    assert str(source) in message and ".part" not in message and "Replace" in message


def test_unreadable_mirror_file_gives_a_data_error(tmp_path, mirror_copy, monkeypatch):
    def denied(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(datasets.shutil, "copyfileobj", denied)
    with pytest.raises(DataError, match=r"oil/DataTrn\.txt: cannot read the mirror file .*Permission denied"):
        fetch("oil/DataTrn.txt", tmp_path / "res", mirror=mirror_copy)
    assert _no_leftovers(tmp_path)


def test_verify_present_names_every_corrupt_file_and_skips_absent_ones(tmp_path, mirror_copy):
    dest = tmp_path / "res"
    assert datasets.verify_present(dest) == []
    path = fetch("oil/DataTrn.txt", dest, mirror=mirror_copy)
    assert datasets.verify_present(dest) == [path]
    path.write_text("<html></html>")
    with pytest.raises(DataError, match=r"oil/DataTrn\.txt: .* has sha256"):
        datasets.verify_present(dest)


def test_library_users_get_the_os_cache_folder_and_a_pooch_registry(tmp_path, monkeypatch):
    monkeypatch.delenv("NLDR_DATA_DIR", raising=False)
    assert datasets.default_data_dir() == pooch.os_cache("nldr")
    monkeypatch.setenv("NLDR_DATA_DIR", str(tmp_path))
    assert datasets.default_data_dir() == tmp_path
    reg = datasets.registry()
    assert set(reg) == set(FILES) and all(reg[k] == f"sha256:{FILES[k].sha256}" for k in FILES)


def test_download_goes_through_pooch_and_checks_the_hash(tmp_path, monkeypatch, mirror_copy):
    """A download from a local HTTP server (no network needed): the file arrives verified; a server
    giving other bytes leaves no file behind and the error names the download."""
    import functools
    import http.server
    import threading

    served = tmp_path / "served"
    shutil.copytree(mirror_copy / "oil", served / "oil")
    (served / "oil" / "garbage.txt").write_text("<html>not the data</html>\n")
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(served))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    monkeypatch.setenv("NO_PROXY", "127.0.0.1")
    try:
        base = f"http://127.0.0.1:{server.server_port}/oil"
        spec = FILES["oil/DataTrn.txt"]
        local = datasets.DataFile(spec.relpath, f"{base}/DataTrn.txt", spec.sha256)
        monkeypatch.setitem(FILES, spec.relpath, local)
        path = fetch(spec.relpath, tmp_path / "res", mirror="")
        assert path == tmp_path / "res" / "oil" / "DataTrn.txt" and datasets.verify(path, spec.relpath)
        wrong = datasets.DataFile(spec.relpath, f"{base}/garbage.txt", spec.sha256)
        monkeypatch.setitem(FILES, spec.relpath, wrong)
        monkeypatch.setattr(datasets, "DOWNLOAD_RETRIES", 0)
        with pytest.raises(DataError, match=r"oil/DataTrn\.txt: download from .*garbage\.txt failed"):
            fetch(spec.relpath, tmp_path / "other", mirror="")
        assert not [p for p in (tmp_path / "other").rglob("*") if p.is_file()]
    finally:
        server.shutdown()
