"""On-board DB bundles: build, reproducibility, verify, tampering, consistency, CLI (planner.bundle: assemble, container, verify)."""
from __future__ import annotations

import base64
import hashlib
import io
import json
import os
import stat
import subprocess
import sys
import tarfile
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from planner import __version__
from planner.bundle.assemble import assemble, line_tables
from planner.bundle.container import build_bundle, build_line, parquet_bytes
from planner.bundle.manifest import CORE_TABLES, EXPECTED_TABLES
from planner.bundle.verify import open_bundle, read_bundle, verify_bundle
from planner.bundle import signing
from planner.errors import BundleError
from test_bundle_support import (LINE_ID, all_tables, release, canonical, forge, make_line, manifest_for, parquet,
                                 synthetic_tables, tar_bytes)

HERE = Path(__file__).parent


@pytest.fixture(scope="module")
def line():
    return make_line()


def build(tables, out, priv, **kw):
    args = dict(line_id=LINE_ID, direction="down", train_type="E10", line_digest="ab" * 32, release=release())
    args.update(kw)
    return build_bundle(tables, out_dir=out, private_key=priv, **args)


@pytest.fixture(scope="module")
def built(tmp_path_factory, keys, line):
    out = tmp_path_factory.mktemp("built")
    info = build(all_tables(line), out, keys[0])
    return Path(info.path), info


# --- build and contents -----------------------------------------------------------
def test_build_writes_one_named_file_that_verifies(built, keys):
    path, info = built
    assert path.name == "tl_down_E10.pdb"
    assert sorted(os.listdir(path.parent)) == [path.name]  # no temp files, no key copies
    assert stat.S_IMODE(path.stat().st_mode) == 0o644
    v = verify_bundle(path, keys[1])
    assert v == info
    assert (v.line_id, v.direction, v.train_type, v.software_version) == (LINE_ID, "down", "E10", __version__)
    assert v.line_digest == "ab" * 32 and v.complete and v.missing == ()
    assert v.sha256 == hashlib.sha256(path.read_bytes()).hexdigest() and v.size_bytes == path.stat().st_size
    assert set(v.tables) == set(CORE_TABLES) | set(EXPECTED_TABLES)


def test_bundle_is_a_standard_tar_with_fixed_metadata(built):
    path, _ = built
    with tarfile.open(path) as tf:
        members = tf.getmembers()
        names = [m.name for m in members]
        assert names == sorted(names)
        assert {"manifest.json", "manifest.sig", "table_b.parquet", "atsp.parquet"} <= set(names)
        for m in members:
            assert m.isreg() and m.mode == 0o644 and m.mtime == 0 and m.uid == m.gid == 0
            assert m.uname == m.gname == ""
        manifest = tf.extractfile("manifest.json").read()
        table_b = pq.read_table(io.BytesIO(tf.extractfile("table_b.parquet").read()))
    m = json.loads(manifest)
    assert manifest == json.dumps(m, sort_keys=True, separators=(",", ":")).encode()
    assert m["schema_version"] == 2 and m["line_id"] == LINE_ID and m["direction"] == "down"
    assert m["train_type"] == "E10" and m["software_version"] == __version__
    by = {e["name"]: e for e in m["files"]}
    with tarfile.open(path) as tf:
        for name, e in by.items():
            data = tf.extractfile(name).read()
            assert e["size"] == len(data) and e["sha256"] == hashlib.sha256(data).hexdigest()
    assert b"pandas" not in (table_b.schema.metadata or {})


def test_read_bundle_returns_the_tables(built, keys, line):
    path, _ = built
    b = read_bundle(path, keys[1])
    src = all_tables(line)
    assert set(b.tables) == set(src)
    for name, t in src.items():
        assert b.tables[name].to_pylist() == t.to_pylist(), name


def test_private_key_never_reaches_the_output(built, keys):
    path, _ = built
    data = path.read_bytes()
    key = keys[2]
    raw = key.private_bytes(serialization.Encoding.Raw, serialization.PrivateFormat.Raw,
                            serialization.NoEncryption())
    pem = keys[0].read_bytes()
    body = b"".join(pem.splitlines()[1:-1])
    for secret in (raw, pem, body, base64.b64encode(raw), raw.hex().encode()):
        assert secret not in data


# --- reproducibility ----------------------------------------------------------------
def test_rebuild_gives_identical_bytes(tmp_path, keys, line):
    a = build(all_tables(line), tmp_path / "a", keys[0])
    b = build(all_tables(make_line()), tmp_path / "b", keys[0])  # fresh objects, same content
    assert Path(a.path).read_bytes() == Path(b.path).read_bytes()
    build(all_tables(line), tmp_path / "a", keys[0])  # over the previous one
    assert Path(a.path).read_bytes() == Path(b.path).read_bytes()


def test_rebuild_in_other_processes_gives_identical_bytes(tmp_path, keys):
    """Different interpreters and hash seeds: nothing process-dependent leaks into the bytes."""
    code = (
        "import sys; sys.path.insert(0, sys.argv[3]);"
        "import test_bundle_support; from test_bundle_support import make_line, all_tables; from planner.bundle.container import build_bundle;"
        "build_bundle(all_tables(make_line()), line_id='tl', direction='down', train_type='E10',"
        " out_dir=sys.argv[1], private_key=sys.argv[2], line_digest='ab'*32, release=test_bundle_support.release())"
    )
    outs = []
    for seed in ("1", "2"):
        out = tmp_path / seed
        env = dict(os.environ, PYTHONHASHSEED=seed)
        subprocess.run([sys.executable, "-c", code, str(out), str(keys[0]), str(HERE)], check=True, env=env)
        outs.append((out / "tl_down_E10.pdb").read_bytes())
    assert outs[0] == outs[1]
    assert outs[0] == Path(build(all_tables(make_line()), tmp_path / "here", keys[0]).path).read_bytes()


def test_parquet_writes_are_deterministic(line):
    t = all_tables(line)["table_b"]
    assert parquet_bytes(t) == parquet_bytes(pa.Table.from_pylist(t.to_pylist()))


def test_pandas_metadata_is_stripped(line):
    t = all_tables(line)["table_a"]
    from_pandas = pa.Table.from_pandas(t.to_pandas(), preserve_index=False)
    assert b"pandas" in from_pandas.schema.metadata
    back = pq.read_table(io.BytesIO(parquet_bytes(from_pandas)))
    assert b"pandas" not in (back.schema.metadata or {})
    assert back.to_pylist() == t.to_pylist()


# --- verify: every single-byte change fails ---------------------------------------------
@pytest.fixture(scope="module")
def small(tmp_path_factory, keys):
    """The smallest complete-enough bundle: the core tables of a line without restrictions."""
    from planner.line import testing

    out = tmp_path_factory.mktemp("small")
    ln = testing.line(line_id=LINE_ID, train_types=[testing.train_type("E10")])
    info = build_bundle(line_tables(ln, "down", "E10"), line_id=LINE_ID, direction="down",
                        train_type="E10", out_dir=out, private_key=keys[0], release=release())
    return Path(info.path)


def test_flipping_any_single_byte_fails_verify(small, keys):
    data = small.read_bytes()
    assert len(data) < 20_000  # keeps this exhaustive test fast
    pub = signing.load_public_key(keys[1])
    verify_bundle(data, pub)  # the bytes, in memory: the same checks as for the file
    survivors = []
    for i in range(len(data)):
        # Every byte with its lowest bit flipped (e.g. '0' -> '1' in an octal header field);
        # every 7th byte also with its top bit flipped.
        for mask in (0x01, 0x80) if i % 7 == 0 else (0x01,):
            b = bytearray(data)
            b[i] ^= mask
            try:
                verify_bundle(bytes(b), pub)
            except BundleError:
                continue
            survivors.append((i, mask))
    assert survivors == []


@pytest.mark.parametrize("cut", [0, 1, 511, 512, 1000, -1025, -1024, -1, "append"])
def test_truncated_or_extended_fails(small, keys, tmp_path, cut):
    data = small.read_bytes()
    data = data + b"\0" * 512 if cut == "append" else data[:cut]
    p = tmp_path / "t.pdb"
    p.write_bytes(data)
    with pytest.raises(BundleError):
        verify_bundle(p, keys[1])


# --- verify: signature, members, manifest -------------------------------------------------
def members_of(path):
    with tarfile.open(path) as tf:
        return {m.name: tf.extractfile(m).read() for m in tf.getmembers()}


def write(tmp_path, raw, name="b.pdb"):
    p = tmp_path / name
    p.write_bytes(raw)
    return p


def test_wrong_key_fails(built, tmp_path):
    path, _ = built
    other = Ed25519PrivateKey.generate().public_key()
    with pytest.raises(BundleError, match="signature does not match"):
        verify_bundle(path, other)


def test_missing_signature_fails(built, keys, tmp_path):
    m = members_of(built[0])
    del m["manifest.sig"]
    with pytest.raises(BundleError, match="manifest.sig is missing"):
        verify_bundle(write(tmp_path, tar_bytes(sorted(m.items()))), keys[1])


def test_missing_manifest_fails(built, keys, tmp_path):
    m = members_of(built[0])
    del m["manifest.json"]
    with pytest.raises(BundleError, match="manifest.json is missing"):
        verify_bundle(write(tmp_path, tar_bytes(sorted(m.items()))), keys[1])


def test_missing_file_fails(built, keys, tmp_path):
    m = members_of(built[0])
    del m["table_b.parquet"]
    with pytest.raises(BundleError, match="missing member.*table_b.parquet"):
        verify_bundle(write(tmp_path, tar_bytes(sorted(m.items()))), keys[1])


def test_extra_file_fails(built, keys, tmp_path):
    m = members_of(built[0])
    m["zz_extra.parquet"] = m["table_a.parquet"]
    with pytest.raises(BundleError, match="extra member.*zz_extra.parquet"):
        verify_bundle(write(tmp_path, tar_bytes(sorted(m.items()))), keys[1])


def test_swapped_member_fails(built, keys, tmp_path):
    m = members_of(built[0])
    m["table_a.parquet"], m["table_b.parquet"] = m["table_b.parquet"], m["table_a.parquet"]
    with pytest.raises(BundleError, match="bytes, the manifest says|SHA-256"):
        verify_bundle(write(tmp_path, tar_bytes(sorted(m.items()))), keys[1])


def test_resigned_by_attacker_fails_with_our_key(built, keys, tmp_path, line):
    evil = Ed25519PrivateKey.generate()
    raw = forge(all_tables(line), evil)
    p = write(tmp_path, raw)
    verify_bundle(p, evil.public_key())  # well-formed, just not ours
    with pytest.raises(BundleError, match="signature"):
        verify_bundle(p, keys[1])


def test_independent_writer_is_accepted(keys, tmp_path, line):
    """A bundle written from the format description alone (tarfile, json, cryptography) verifies."""
    p = write(tmp_path, forge(all_tables(line), keys[2]))
    info = verify_bundle(p, keys[1])
    assert info.complete and info.software_version == "test"


@pytest.mark.parametrize("change, msg", [
    (dict(schema_version=1), "schema version 1 not supported"),
    (dict(schema_version=3), "schema version 3 not supported"),
    (dict(format="other"), "format"),
    (dict(direction="sideways"), "direction"),
    (dict(train_type="E6"), "column train_type holds"),
    (dict(line_id="other"), "column line holds"),
    (dict(extra_key="x"), "unknown"),
    (dict(line_digest="nothex"), "line_digest"),
    (dict(schema_version="2"), "schema_version"),
    (dict(key_kind="staging"), "key_kind"),
    (dict(bundle_version=0), "bundle_version"),
    (dict(built_at="2026-13-01T00:00:00Z"), "built_at"),
    (dict(expires="2025-01-01T00:00:00Z"), "not after built_at"),
    (dict(missing=["table_a"]), "missing"),
])
def test_bad_manifest_fails_even_when_signed(keys, tmp_path, line, change, msg):
    p = write(tmp_path, forge(all_tables(line), keys[2], **change))
    with pytest.raises(BundleError, match=msg):
        verify_bundle(p, keys[1])


def test_non_canonical_manifest_fails_even_when_signed(keys, tmp_path, line):
    tables = all_tables(line)
    files = {f"{n}.parquet": parquet(t) for n, t in tables.items()}
    m = manifest_for(files, {f"{n}.parquet": t.num_rows for n, t in tables.items()}, key=keys[2])
    pretty = json.dumps(m, sort_keys=True, indent=1).encode()
    with pytest.raises(BundleError, match="canonical"):
        verify_bundle(write(tmp_path, forge(tables, keys[2], manifest=pretty)), keys[1])
    dup = canonical(m)[:-1] + b',"format":"planner-onboard-db"}'
    with pytest.raises(BundleError, match="duplicate key"):
        verify_bundle(write(tmp_path, forge(tables, keys[2], manifest=dup)), keys[1])


# --- verify: internal consistency (validly signed, wrong content) ----------------------------
def forged_with(keys, tmp_path, line, edit):
    tables = all_tables(line)
    edit(tables)
    return write(tmp_path, forge(tables, keys[2]))


def test_table_b_ratio_missing_from_table_a_fails(keys, tmp_path, line):
    def edit(t):
        t["table_a"] = t["table_a"].filter(pa.compute.not_equal(t["table_a"]["ratio"], 0.6))
    with pytest.raises(BundleError, match="table_b ratio_before 0.6 .* not in table_a"):
        verify_bundle(forged_with(keys, tmp_path, line, edit), keys[1])


def test_table_c_ratio_missing_from_table_a_fails(keys, tmp_path, line):
    def edit(t):  # table (c) for a ratio the vehicle has no column (a) for
        t["table_c"] = t["table_c"].set_column(
            t["table_c"].column_names.index("ratio"), "ratio",
            pa.compute.multiply(t["table_c"]["ratio"], 0.5))
    with pytest.raises(BundleError, match="table_c ratio .* not in table_a"):
        verify_bundle(forged_with(keys, tmp_path, line, edit), keys[1])


def test_table_d_point_missing_from_eval_points_fails(keys, tmp_path, line):
    """Verify reads table (d) a row group at a time with its text dictionary-encoded: an evaluation point that
    eval_points lacks, in its last row alone, is still named."""
    def edit(t):
        td = t["table_d"]
        ids = td["eval_point_id"].to_pylist()
        ids[-1] = "dep+999"
        t["table_d"] = td.set_column(td.schema.get_field_index("eval_point_id"), "eval_point_id", pa.array(ids))
    with pytest.raises(BundleError, match=r"table_d evaluation point 'dep\+999' for .* is not in eval_points"):
        verify_bundle(forged_with(keys, tmp_path, line, edit), keys[1])


def test_foreign_train_type_rows_fail(keys, tmp_path, line):
    def edit(t):
        t["table_a"] = synthetic_tables(line, "down", "E6")["table_a"]
    with pytest.raises(BundleError, match="table table_a column train_type holds \\['E6'\\]"):
        verify_bundle(forged_with(keys, tmp_path, line, edit), keys[1])


def test_other_direction_table_fails(keys, tmp_path, line):
    def edit(t):
        t["beacons"] = line_tables(line, "up", "E10")["beacons"]
    with pytest.raises(BundleError, match="column direction"):
        verify_bundle(forged_with(keys, tmp_path, line, edit), keys[1])


def reseq(t: pa.Table) -> pa.Table:
    """Renumber ``seq`` 0..n-1 so that only the intended inconsistency remains."""
    i = t.schema.get_field_index("seq")
    return t.set_column(i, t.schema.field(i), pa.array(range(t.num_rows), type=pa.int32()))


@pytest.mark.parametrize("what, msg", [
    ("flags", "correction_usable flags do not match"),
    ("atsp_row", "atsp rows do not match the restrictions marked db_fed"),
    ("schema", "restrictions does not match its declared schema .*overwrites"),
    ("eval_point", "not in eval_points|beacon\\(s\\) \\['B9'\\]"),
    ("profile", "max_profile segments are not contiguous"),
])
def test_inconsistent_core_tables_fail(keys, tmp_path, line, what, msg):
    def edit(t):
        if what == "flags":
            b = t["beacons"]
            t["beacons"] = b.set_column(b.schema.get_field_index("correction_usable"), b.schema.field(
                "correction_usable"), pa.array([True] * b.num_rows))
        elif what == "atsp_row":
            t["atsp"] = reseq(t["atsp"].slice(1))
        elif what == "schema":
            t["restrictions"] = t["restrictions"].drop_columns(["overwrites"])
        elif what == "eval_point":
            e = t["eval_points"]
            ids = e["eval_point_id"].to_pylist()
            t["eval_points"] = e.set_column(e.schema.get_field_index("eval_point_id"), "eval_point_id",
                                            pa.array([x.replace("B3", "B9") for x in ids]))
        else:
            p = t["max_profile"]
            t["max_profile"] = reseq(pa.concat_tables([p.slice(0, 1), p.slice(2)]))
    with pytest.raises(BundleError, match=msg):
        verify_bundle(forged_with(keys, tmp_path, line, edit), keys[1])


def test_builder_refuses_what_verify_would_refuse(keys, tmp_path, line):
    tables = all_tables(line)
    tables["table_a"] = tables["table_a"].slice(0, 1)
    with pytest.raises(BundleError, match="not in table_a"):
        build(tables, tmp_path, keys[0])
    tables = all_tables(line)
    del tables["atsp"]
    with pytest.raises(BundleError, match="without the atsp"):
        build(tables, tmp_path, keys[0])
    with pytest.raises(BundleError, match="cannot name a bundle"):
        build(all_tables(line), tmp_path, keys[0], train_type="../E10")
    assert os.listdir(tmp_path) == []


def test_partial_bundle_lists_what_is_missing(keys, tmp_path, line):
    info = build(line_tables(line, "down", "E10"), tmp_path, keys[0])
    v = verify_bundle(info.path, keys[1])
    assert not v.complete and v.missing == tuple(sorted(EXPECTED_TABLES))
    assert "PARTIAL" in v.summary()[-1]


# --- atomic write: errors leave nothing behind -----------------------------------------------
def test_failed_write_keeps_previous_bundle_and_no_temp(keys, tmp_path, line, monkeypatch):
    info = build(all_tables(line), tmp_path, keys[0])
    before = Path(info.path).read_bytes()

    def boom(fd):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", boom)
    tables = all_tables(line, ratios=(1.0, 0.5))  # different content
    with pytest.raises(OSError, match="No space left on device") as e:  # each caller names its own fix
        build(tables, tmp_path, keys[0])
    assert e.value.errno == 28 and str(e.value.filename) == str(info.path)
    monkeypatch.undo()
    assert os.listdir(tmp_path) == [Path(info.path).name]
    assert Path(info.path).read_bytes() == before


# --- open_bundle -------------------------------------------------------------------
def test_open_bundle_writes_members_only_into_dest(built, keys, tmp_path):
    dest = tmp_path / "dest"
    info = open_bundle(built[0], dest, keys[1])
    assert sorted(os.listdir(dest)) == sorted([f.name for f in info.files] + ["manifest.json", "manifest.sig"])
    assert os.listdir(tmp_path) == ["dest"]


def test_open_bundle_never_follows_a_planted_symlink(built, keys, tmp_path):
    dest = tmp_path / "dest"
    dest.mkdir()
    victim = tmp_path / "victim"
    victim.write_bytes(b"keep")
    (dest / "atsp.parquet").symlink_to(victim)
    with pytest.raises(BundleError, match="already exists"):
        open_bundle(built[0], dest, keys[1])
    assert victim.read_bytes() == b"keep"


def test_open_bundle_writes_nothing_when_verify_fails(built, tmp_path):
    dest = tmp_path / "dest"
    with pytest.raises(BundleError):
        open_bundle(built[0], dest, Ed25519PrivateKey.generate().public_key())
    assert not dest.exists() or os.listdir(dest) == []


# --- assembler and CLI ---------------------------------------------------------------
def write_datasets(root, line, direction, train_type, names):
    from planner.io.parquet import write_partitioned

    t = synthetic_tables(line, direction, train_type)
    for n in names:
        write_partitioned(t[n], root, n)


def test_assemble_reads_the_partitions_that_exist(tmp_path, line):
    write_datasets(tmp_path / "tables", line, "down", "E10", ["eval_points", "table_a", "table_b"])
    write_datasets(tmp_path / "stops", line, "down", "E10", ["stop_summary"])
    t = assemble(line, "down", "E10", tables_dir=tmp_path / "tables", stops_dir=tmp_path / "stops")
    assert set(t) == set(CORE_TABLES) | {"eval_points", "table_a", "table_b", "stop_summary"}
    src = synthetic_tables(line, "down", "E10")
    assert sorted(t["table_b"].to_pylist(), key=str) == sorted(src["table_b"].to_pylist(), key=str)
    other = assemble(line, "down", "E6", tables_dir=tmp_path / "tables")
    assert "table_a" not in other  # no partition for E6: left out, listed as missing later
    with pytest.raises(BundleError, match="not a folder"):
        assemble(line, "down", "E10", tables_dir=tmp_path / "nope")


def test_build_line_builds_every_direction_and_type(tmp_path, keys, line):
    write_datasets(tmp_path / "tables", line, "down", "E10", ["eval_points", "table_a", "table_b"])
    infos = build_line(line, tmp_path / "out", keys[0], release=release(), tables_dir=tmp_path / "tables")
    names = sorted(Path(i.path).name for i in infos)
    assert names == ["tl_down_E10.pdb", "tl_down_E6.pdb", "tl_up_E10.pdb", "tl_up_E6.pdb"]
    for i in infos:
        v = verify_bundle(i.path, keys[1])
        has_tables = (v.direction, v.train_type) == ("down", "E10")
        assert ("table_b" in v.tables) == has_tables


def run_cli(*args, env=None):
    from typer.testing import CliRunner

    from planner.cli import app

    return CliRunner().invoke(app, list(map(str, args)), env=env)


def test_cli_keys_build_verify(tmp_path):
    from linedb import write_line_db

    line_dir = write_line_db(tmp_path / "tiny")
    r = run_cli("keys", "generate", tmp_path / "k")
    assert r.exit_code == 0, r.output
    priv, pub = tmp_path / "k" / "signing_key.pem", tmp_path / "k" / "signing_key.pub.pem"
    r = run_cli("keys", "generate", tmp_path / "k")
    assert r.exit_code != 0 and "refusing to overwrite" in r.output
    r = run_cli("bundle", "build", line_dir, "--out", tmp_path / "out", "--train-type", "EMU10",
                "--direction", "down", env={"PLANNER_SIGNING_KEY": str(priv), "SOURCE_DATE_EPOCH": "1767225600"})
    assert r.exit_code == 0, r.output
    path = tmp_path / "out" / "tiny_down_EMU10.pdb"
    assert os.listdir(tmp_path / "out") == [path.name]
    r = run_cli("bundle", "verify", path, "--public-key", pub, "--expect", "tiny/down/EMU10",
                "--at", "2026-01-02T00:00:00Z")
    assert r.exit_code == 0, r.output
    assert "OK" in r.output and "tiny" in r.output and "PARTIAL" in r.output
    assert "version 20260101000000, built 2026-01-01T00:00:00Z, expires 2026-01-31T00:00:00Z" in r.output
    r = run_cli("bundle", "verify", path, "--public-key", pub, "--expect", "tiny/down/EMU10",
                "--at", "2026-01-02T00:00:00Z", "--require-complete")
    assert r.exit_code != 0
    # Same line, same key, same build time: same bytes, also through the CLI with --key and --built-at.
    first = path.read_bytes()
    r = run_cli("bundle", "build", line_dir, "--out", tmp_path / "out2", "--key", priv,
                "--train-type", "EMU10", "--direction", "down", "--built-at", "2026-01-01T00:00:00Z")
    assert r.exit_code == 0 and (tmp_path / "out2" / path.name).read_bytes() == first
    info = verify_bundle(path, pub, at="2026-01-02T00:00:00Z")
    from planner.line.loader import source_digest

    assert info.line_digest == source_digest(line_dir)


def test_cli_failures_are_one_line(tmp_path, built):
    from linedb import write_line_db

    line_dir = write_line_db(tmp_path / "tiny")
    r = run_cli("bundle", "build", line_dir, "--out", tmp_path / "out", env={"PLANNER_SIGNING_KEY": ""})
    assert r.exit_code != 0 and "signing key" in r.output
    other = tmp_path / "o"
    signing.generate_keypair(other)
    r = run_cli("bundle", "verify", built[0], "--public-key", other / "signing_key.pub.pem", "--expect", "tl/down/E10")
    assert r.exit_code != 0
    lines = [x for x in r.output.splitlines() if x.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: bundle") and "signature" in lines[0]
    assert "Traceback" not in r.output


def test_cli_build_on_a_full_disk_is_one_line_naming_out(tmp_path, keys, monkeypatch):
    from linedb import write_line_db

    from planner.bundle import container

    def full(path, data):
        raise OSError(28, "No space left on device", str(path))

    monkeypatch.setattr(container, "write_atomic", full)
    line_dir = write_line_db(tmp_path / "tiny")
    r = run_cli("bundle", "build", line_dir, "--out", tmp_path / "out", "--key", keys[0])
    lines = [x for x in r.output.splitlines() if x.strip()]
    assert r.exit_code != 0 and len(lines) == 1, r.output
    assert lines[0] == (f"error: cannot write {tmp_path / 'out' / 'tiny_down_EMU10.pdb'}: No space left on device; "
                        "check --out (space, permissions)")


def test_table_without_required_columns_is_refused(keys, tmp_path, line):
    tables = all_tables(line)
    tables["table_b"] = tables["table_b"].drop_columns(["ratio_after"])
    with pytest.raises(BundleError, match="table table_b lacks column\\(s\\) ratio_after"):
        build(tables, tmp_path, keys[0])
    with pytest.raises(BundleError, match="lacks column"):
        verify_bundle(write(tmp_path, forge(tables, keys[2])), keys[1])


def test_assemble_refuses_a_stored_partition_column_that_disagrees(tmp_path, line):
    folder = tmp_path / "tables" / "table_a" / f"line={LINE_ID}" / "direction=down" / "train_type=E10"
    folder.mkdir(parents=True)
    pq.write_table(synthetic_tables(line, "down", "E6")["table_a"], folder / "part-0.parquet")
    with pytest.raises(BundleError, match="column train_type holds \\['E6'\\]"):
        assemble(line, "down", "E10", tables_dir=tmp_path / "tables")


# --- the steps' tables given as the bytes a bundle holds them in (the nightly job's previous bundle) ------------
def _given(tables: dict) -> tuple[dict, dict]:
    """The steps' tables as their member bytes, and the tables a build is then given: the line's own and the two
    given ones it decodes (eval_points, stop_summary), from those bytes."""
    from planner.bundle.container import DECODED_GIVEN, STEP_TABLES

    given = {n: parquet_bytes(tables[n]) for n in STEP_TABLES if n in tables}
    rest = {n: t for n, t in tables.items() if n not in given}
    return given, rest | {n: pq.read_table(pa.BufferReader(given[n])) for n in DECODED_GIVEN if n in given}


def test_steps_tables_given_as_their_bytes_make_the_same_bundle(keys, tmp_path, line):
    """Given as the bytes a bundle holds them in, the steps' tables make the same bundle, byte for byte, as the
    tables encoded; only the steps' tables may be given."""
    tables = all_tables(line)
    given, rest = _given(tables)
    assert {"table_d", "stop_samples", "eval_points"} <= set(given) and "table_d" not in rest
    a = build(tables, tmp_path / "a", keys[0])
    b = build(rest, tmp_path / "b", keys[0], given=given)
    assert Path(a.path).read_bytes() == Path(b.path).read_bytes()
    assert verify_bundle(b.path, keys[1]).complete
    with pytest.raises(BundleError, match="only the steps' tables"):
        build(tables, tmp_path / "c", keys[0], given={"restrictions": parquet_bytes(tables["restrictions"])})


def test_given_eval_points_are_checked_against_this_bundles_beacons(keys, tmp_path, line):
    """The line's own tables are made again with given steps' tables: evaluation points that name a beacon the line
    no longer has are refused, as when the tables are encoded; nothing is written."""
    tables = all_tables(line)
    ep = tables["eval_points"]
    kinds = ep.column("eval_point_kind").to_pylist() if "eval_point_kind" in ep.column_names else None
    ids = ep.column("eval_point_id").to_pylist()
    gone = next(x for i, x in enumerate(ids) if (kinds[i] == "beacon" if kinds else not x.startswith("dep")))
    b = tables["beacons"]
    i = b.schema.get_field_index("beacon_id")  # the line's beacon renamed: the evaluation point names none
    tables["beacons"] = b.set_column(i, b.schema.field(i), pa.array(
        ["ZZ9" if x == gone else x for x in b.column(i).to_pylist()], type=b.schema.field(i).type))
    given, rest = _given(tables)
    with pytest.raises(BundleError, match="eval_points name beacon"):
        build(rest, tmp_path, keys[0], given=given)
    assert not list(tmp_path.iterdir())
