"""Opening a bundle into a folder is all or nothing (issue 32, item 5).

A refusal at any point after verification (the destination holds a symbolic link or anything else,
is itself a link or a file, the disk fills at a member, the destination changes meanwhile) leaves
every file under the test's folder exactly as it was: same names, same kinds, same bytes, same link
targets, and no temporary folder. Before, a planted link under the last member's name was refused
after the other members had been written.
"""
from __future__ import annotations

import errno
import io
import os
import tarfile
from pathlib import Path

import pytest
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

import planner.bundle.verify as verify
from planner.bundle.assemble import line_tables
from planner.bundle.container import bundle_bytes
from planner.bundle.verify import open_bundle
from planner.errors import BundleError
from planner.line import testing
from test_bundle_support import LINE_ID, release

KEY = Ed25519PrivateKey.generate()
PUB = KEY.public_key()


@pytest.fixture(scope="module")
def bundle(tmp_path_factory) -> tuple[Path, dict[str, bytes]]:
    """A good bundle file and its members (read with the standard tarfile module)."""
    ln = testing.line(line_id=LINE_ID, train_types=[testing.train_type("E10")])
    data = bundle_bytes(line_tables(ln, "down", "E10"), line_id=LINE_ID, direction="down", train_type="E10",
                        private_key=KEY, release=release())
    p = tmp_path_factory.mktemp("bundle") / "b.pdb"
    p.write_bytes(data)
    with tarfile.open(fileobj=io.BytesIO(data)) as tf:
        members = {m.name: tf.extractfile(m).read() for m in tf.getmembers()}
    assert len(members) >= 3
    return p, members


def tree(root: Path) -> dict[str, tuple]:
    """Everything under ``root``, never following a link: kind and bytes, or link target."""
    out = {}
    for dirpath, dirs, files in os.walk(root):
        for name in dirs + files:
            p = Path(dirpath) / name
            rel = p.relative_to(root).as_posix()
            if p.is_symlink():
                out[rel] = ("link", os.readlink(p))
            elif p.is_dir():
                out[rel] = ("dir", oct(p.stat().st_mode & 0o777))
            else:
                out[rel] = ("file", p.read_bytes())
    return out


def refused(bundle, dest: Path, root: Path, match: str) -> None:
    before = tree(root)
    with pytest.raises(BundleError, match=match):
        open_bundle(bundle[0], dest, PUB, allow_dev=True)
    assert tree(root) == before  # nothing added, removed or changed; no temporary folder


def test_a_destination_holding_a_link_under_the_last_members_name_is_refused_and_left_alone(bundle, tmp_path):
    dest = tmp_path / "dest"
    dest.mkdir()
    victim = tmp_path / "victim"
    victim.write_bytes(b"keep")
    last = sorted(bundle[1])[-1]
    (dest / last).symlink_to(victim)
    refused(bundle, dest, tmp_path, "already exists")  # the other members were written before
    assert os.listdir(dest) == [last] and victim.read_bytes() == b"keep"


@pytest.mark.parametrize("entry", ["link", "dangling_link", "file", "folder"])
def test_a_destination_holding_anything_is_refused_and_left_alone(bundle, tmp_path, entry):
    dest = tmp_path / "dest"
    dest.mkdir()
    (tmp_path / "elsewhere").mkdir()
    if entry == "link":
        (dest / "notes").symlink_to(tmp_path / "elsewhere")
    elif entry == "dangling_link":
        (dest / "notes").symlink_to(tmp_path / "nowhere")
    elif entry == "file":
        (dest / "notes").write_bytes(b"mine")
    else:
        (dest / "notes").mkdir()
    refused(bundle, dest, tmp_path, "is not empty .*'notes'")
    assert os.listdir(tmp_path / "elsewhere") == []


def test_a_destination_that_is_a_link_or_a_file_is_refused_and_left_alone(bundle, tmp_path):
    target = tmp_path / "real"
    target.mkdir()
    (tmp_path / "dest").symlink_to(target)  # a link to an empty folder: never written through
    refused(bundle, tmp_path / "dest", tmp_path, "is a symbolic link")
    (tmp_path / "file").write_bytes(b"mine")
    refused(bundle, tmp_path / "file", tmp_path, "is not a folder")


def test_a_full_disk_at_a_member_leaves_nothing(bundle, tmp_path, monkeypatch):
    real = os.fdopen
    writes = []

    class Full(io.RawIOBase):  # the third member's write fails as on a full disk
        def __init__(self, fd):
            self.f = real(fd, "wb")

        def write(self, data):
            writes.append(len(data))
            if len(writes) == 3:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            return self.f.write(data)

        def close(self):
            self.f.close()
            super().close()

    monkeypatch.setattr(os, "fdopen", lambda fd, mode="r", *a, **k: Full(fd) if mode == "wb" else real(fd, mode))
    refused(bundle, tmp_path / "new" / "deeper" / "dest", tmp_path, "No space left on device; nothing was written")
    assert len(writes) == 3 and os.listdir(tmp_path) == []  # the parent folders it made are gone too


def test_a_destination_filled_meanwhile_is_refused_and_keeps_what_was_put_there(bundle, tmp_path, monkeypatch):
    dest = tmp_path / "dest"
    real = verify._write_members

    def and_someone_writes_into_dest(folder, members):
        real(folder, members)
        dest.mkdir()
        (dest / "theirs").write_bytes(b"theirs")  # after the check, before the rename

    monkeypatch.setattr(verify, "_write_members", and_someone_writes_into_dest)
    with pytest.raises(BundleError, match="no longer missing or empty"):
        open_bundle(bundle[0], dest, PUB, allow_dev=True)
    assert tree(tmp_path) == {"dest": ("dir", oct(dest.stat().st_mode & 0o777)), "dest/theirs": ("file", b"theirs")}


@pytest.mark.parametrize("exists", [False, True])
def test_a_new_or_empty_destination_gets_exactly_the_members(bundle, tmp_path, exists):
    dest = tmp_path / "a" / "dest"
    if exists:
        dest.mkdir(parents=True)
    info = open_bundle(bundle[0], dest, PUB, allow_dev=True)
    assert info.target == f"{LINE_ID}/down/E10"
    assert tree(tmp_path) == {"a": tree(tmp_path)["a"], "a/dest": ("dir", "0o755"),
                              **{f"a/dest/{n}": ("file", d) for n, d in bundle[1].items()}}
    assert all((dest / n).stat().st_mode & 0o777 == 0o644 for n in bundle[1])
