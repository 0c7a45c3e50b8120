"""Hostile archives: reading a bundle never writes outside the target and refuses bad members."""
from __future__ import annotations

import io
import os
import tarfile
from pathlib import Path

import pytest
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from planner.bundle import archive, container
from planner.bundle.archive import tar_header
from planner.bundle.assemble import line_tables
from planner.bundle.container import build_bundle, bundle_bytes
from planner.bundle.manifest import MAX_MEMBERS, MAX_TOTAL_BYTES
from planner.bundle.verify import open_bundle, read_bundle, verify_bundle
from planner.line import testing
from planner.errors import BundleError
from test_bundle_support import LINE_ID, release, tar_bytes

KEY = Ed25519PrivateKey.generate()
PUB = KEY.public_key()


@pytest.fixture(scope="module")
def good_members():
    ln = testing.line(line_id=LINE_ID, train_types=[testing.train_type("E10")])
    data = bundle_bytes(line_tables(ln, "down", "E10"), line_id=LINE_ID, direction="down",
                        train_type="E10", private_key=KEY, release=release())
    with tarfile.open(fileobj=io.BytesIO(data)) as tf:
        return {m.name: tf.extractfile(m).read() for m in tf.getmembers()}


def info(name, type_=tarfile.REGTYPE, linkname="", size=0):
    ti = tarfile.TarInfo(name)
    ti.type, ti.linkname, ti.size, ti.mode = type_, linkname, size, 0o644
    return ti


def snapshot(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")} | {str(p.relative_to(root)) for p in
                                                                    root.rglob(".*")}


def assert_refused(tmp_path, raw: bytes, match: str, good_members=None):
    """verify_bundle and open_bundle both refuse; nothing appears anywhere under tmp_path."""
    case = tmp_path / "case"
    (case / "outside").mkdir(parents=True)
    p = case / "b.pdb"
    p.write_bytes(raw)
    before = snapshot(tmp_path)
    with pytest.raises(BundleError, match=match):
        verify_bundle(p, PUB)
    with pytest.raises(BundleError, match=match):
        open_bundle(p, case / "dest", PUB)
    with pytest.raises(BundleError, match=match):
        read_bundle(raw, PUB)
    assert snapshot(tmp_path) == before  # not even an empty dest folder
    assert not any("evil" in x for x in snapshot(tmp_path) - {"case/b.pdb"})


def with_good(good, *extra):
    """The good members plus hostile ones, sorted by name like a real bundle."""
    items = [(n, d) for n, d in good.items()] + list(extra)
    return sorted(items, key=lambda x: x[0].name if isinstance(x[0], tarfile.TarInfo) else x[0])


@pytest.mark.parametrize("name", ["../evil.parquet", "sub/../../evil.parquet", "../../outside/evil.parquet",
                                  "./atsp.parquet", "dir/evil.parquet", "..\\evil.parquet"])
def test_path_traversal_refused(tmp_path, good_members, name):
    raw = tar_bytes(with_good(good_members, (name, b"PAR1evil")))
    assert_refused(tmp_path, raw, "is a path|not allowed")


def test_absolute_path_refused(tmp_path, good_members):
    target = str(tmp_path / "case" / "outside" / "evil.parquet")
    raw = tar_bytes(with_good(good_members, (target, b"PAR1evil")))
    assert_refused(tmp_path, raw, "is a path")


@pytest.mark.parametrize("type_, link, what", [
    (tarfile.SYMTYPE, "/etc/passwd", "symbolic link"),
    (tarfile.SYMTYPE, "../outside", "symbolic link"),
    (tarfile.LNKTYPE, "../outside/evil", "hard link"),
    (tarfile.LNKTYPE, "table_b.parquet", "hard link"),
    (tarfile.CHRTYPE, "", "character device"),
    (tarfile.BLKTYPE, "", "block device"),
    (tarfile.FIFOTYPE, "", "FIFO"),
    (tarfile.DIRTYPE, "", "directory"),
])
def test_links_devices_and_other_non_regular_members_refused(tmp_path, good_members, type_, link, what):
    raw = tar_bytes(with_good(good_members, (info("atsp_evil.parquet", type_, link), None)))
    assert_refused(tmp_path, raw, what)


def test_link_replacing_a_real_member_refused(tmp_path, good_members):
    members = dict(good_members)
    del members["atsp.parquet"]
    raw = tar_bytes(with_good(members, (info("atsp.parquet", tarfile.SYMTYPE, "/etc/passwd"), None)))
    assert_refused(tmp_path, raw, "symbolic link")


def test_duplicate_member_refused(tmp_path, good_members):
    raw = tar_bytes(with_good(good_members, ("atsp.parquet", good_members["atsp.parquet"])))
    assert_refused(tmp_path, raw, "duplicate member 'atsp.parquet'")


@pytest.mark.parametrize("fmt, what", [(tarfile.PAX_FORMAT, "pax header"), (tarfile.GNU_FORMAT, "GNU long name")])
def test_extended_headers_refused(tmp_path, good_members, fmt, what):
    raw = tar_bytes([("evil_" + "x" * 120 + ".parquet", b"data")], fmt=fmt)
    assert_refused(tmp_path, raw, what)


def header_with_size(name: str, size_field: bytes) -> bytes:
    """A ustar header whose size field says ``size_field`` (checksum kept valid)."""
    h = bytearray(tar_header(name, 0))
    h[124:136] = size_field
    h[148:156] = b" " * 8
    h[148:156] = format(sum(h), "06o").encode() + b"\0 "
    return bytes(h)


def test_huge_declared_member_refused_before_reading(tmp_path):
    # 300 MiB declared, 1 KiB present: refused on the header alone, above the 256 MiB bound.
    raw = header_with_size("table_b.parquet", b"%011o\0" % (300 * 1024**2)) + b"\0" * 1024 + b"\0" * 1024
    assert_refused(tmp_path, raw, "above the .*-byte bound")


def test_declared_size_beyond_end_of_file_refused(tmp_path):
    raw = header_with_size("table_b.parquet", b"%011o\0" % (100 * 1024**2)) + b"\0" * 2048
    assert_refused(tmp_path, raw, "truncated")


def test_base256_size_field_refused(tmp_path):
    raw = header_with_size("table_b.parquet", b"\x80" + b"\0" * 7 + b"\x10\0\0\0") + b"\0" * 2048
    assert_refused(tmp_path, raw, "not a plain octal number")


def test_oversized_file_refused_without_reading(tmp_path):
    p = tmp_path / "huge.pdb"
    with open(p, "wb") as f:
        f.truncate(MAX_TOTAL_BYTES + 10 * 1024**2)  # sparse: costs no disk, no memory
    with pytest.raises(BundleError, match="above the"):
        verify_bundle(p, PUB)


def test_member_above_bound_refused_on_read_and_build(tmp_path, good_members, monkeypatch):
    raw = tar_bytes(sorted(good_members.items()))
    read_bundle(raw, PUB)
    for module in (archive, container):  # the reader's bound and the builder's
        monkeypatch.setattr(module, "MAX_MEMBER_BYTES", 1000)
    with pytest.raises(BundleError, match="above the 1000-byte bound"):
        read_bundle(raw, PUB)
    ln = testing.line(line_id=LINE_ID, train_types=[testing.train_type("E10")])
    with pytest.raises(BundleError, match="above the 1000-byte member bound"):
        build_bundle(line_tables(ln, "down", "E10"), line_id=LINE_ID, direction="down",
                     train_type="E10", out_dir=tmp_path / "out", private_key=KEY, release=release())
    assert not (tmp_path / "out").exists() or os.listdir(tmp_path / "out") == []


def test_too_many_members_refused(tmp_path):
    raw = tar_bytes([(f"t{i:03d}.parquet", b"x") for i in range(MAX_MEMBERS + 1)])
    assert_refused(tmp_path, raw, "more than")


def test_non_regular_bundle_paths_refused(tmp_path):
    fifo = tmp_path / "fifo.pdb"
    os.mkfifo(fifo)
    with pytest.raises(BundleError, match="not a regular file"):
        verify_bundle(fifo, PUB)  # returns at once: opened non-blocking
    with pytest.raises(BundleError):
        verify_bundle(tmp_path, PUB)
    with pytest.raises(BundleError, match="not found"):
        verify_bundle(tmp_path / "none.pdb", PUB)


def test_non_canonical_header_fields_refused(tmp_path, good_members):
    """A standard tar of the right members but with an owner name, a date and mode 0755."""
    items = []
    for n, d in sorted(good_members.items()):
        ti = tarfile.TarInfo(n)
        ti.size, ti.mtime, ti.uname, ti.mode = len(d), 1_700_000_000, "mallory", 0o755
        items.append((ti, d))
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w", format=tarfile.USTAR_FORMAT) as tf:
        for ti, d in items:
            tf.addfile(ti, io.BytesIO(d))
    raw = buf.getvalue().rstrip(b"\0")
    raw += b"\0" * (-len(raw) % 512) + b"\0" * 1024
    assert_refused(tmp_path, raw, "non-canonical header")


def test_unsorted_members_refused(tmp_path, good_members):
    raw = tar_bytes(sorted(good_members.items(), reverse=True))
    assert_refused(tmp_path, raw, "sorted order")


def test_good_bundle_opens_only_into_dest(tmp_path, good_members):
    raw = tar_bytes(sorted(good_members.items()))
    p = tmp_path / "b.pdb"
    p.write_bytes(raw)
    open_bundle(p, tmp_path / "dest", PUB)
    assert sorted(os.listdir(tmp_path)) == ["b.pdb", "dest"]
    assert sorted(os.listdir(tmp_path / "dest")) == sorted(good_members)
    for n, d in good_members.items():
        assert (tmp_path / "dest" / n).read_bytes() == d


def test_a_file_that_is_no_tar_is_refused_without_showing_its_text(tmp_path):
    """`bundle verify README.md` printed the file's first line as a member name "of unknown type"."""
    text = b"# planner\n\nsecret first words of some text file\n" * 40
    assert_refused(tmp_path, text + b"\0" * (-len(text) % 512), "not a bundle: no tar header at byte 0")
    with pytest.raises(BundleError) as e:
        path = tmp_path / "t.pdb"
        path.write_bytes(text + b"\0" * (-len(text) % 512))
        verify_bundle(path, PUB)
    assert "secret" not in str(e.value)
