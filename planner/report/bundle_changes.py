"""What changed in the bundles between two runs: members whose content differs, with the rows that differ.

Part of :func:`planner.report.changes.compare_runs` (the ``bundle`` rows of the ``changes``
dataset). Both bundles are checked against their own run's public key (the signature, every member's
digest; only the tables whose digests differ are decoded, one at a time, so a network's bundles compare
in the memory of the tables that changed),
whatever kind of key signed them and whenever they are valid (a comparison loads nothing onto a vehicle:
the previous run's bundles are for the previous operating day); a change of key kind is a row of its own.
"""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from planner.report.changes import LineChanges


MANIFEST_CONTENT = (("line_digest", "line database digest"), ("software_version", "software version"),
                    ("schema_version", "bundle format version"), ("key_id", "signing key"),
                    ("missing", "list of missing tables"))
"""Manifest fields that say something about a bundle's content; the release fields (version, build time,
expiry) change at every build, so two bundles that differ only there hold the same content."""


def bundle_changes(ch: LineChanges, old_dir: Path, new_dir: Path) -> None:
    """Add the rows of the line's bundles that changed from ``old_dir`` to ``new_dir``."""
    import re

    from planner.bundle.verify import Expect, read_signed
    from planner.errors import PlannerError
    from planner.line.model import DIRECTIONS

    whenever = Expect(allow_dev=True, check_time=False)

    ob, nb = Path(old_dir) / "bundles", Path(new_dir) / "bundles"
    # the line's own: <line>_<direction>_<type>.pdb (line "a" is not given line "a_b"'s bundles)
    mine = re.compile(rf"{re.escape(ch.line_id)}_({'|'.join(DIRECTIONS)})_[A-Za-z0-9][A-Za-z0-9._-]*\.pdb")
    names = sorted({p.name for d in (ob, nb) if d.is_dir() for p in d.glob(f"{ch.line_id}_*.pdb")
                    if mine.fullmatch(p.name)})
    for name in names:
        po, pn = ob / name, nb / name
        if not po.is_file() or not pn.is_file():
            ch.add("bundle", name, f"bundle {name} {'added' if pn.is_file() else 'removed'}", field_="row",
                   before="" if pn.is_file() else name, after=name if pn.is_file() else "")
            continue
        if _same_bytes(po, pn):
            continue
        try:  # compared whatever kind of key signed them (a comparison loads nothing onto a vehicle)
            a_info, a_members = read_signed(po, ob / "signing_key.pub.pem", expect=whenever)
            b_info, b_members = read_signed(pn, nb / "signing_key.pub.pem", expect=whenever)
        except PlannerError as e:  # named by run id, not by this machine's paths
            why = str(e).replace(str(Path(old_dir)), ch.base_run).replace(str(Path(new_dir)), ch.run)
            ch.add("bundle", name, f"bundle {name} changed but could not be compared: {why}", field_="sha256")
            continue
        d, t = _bundle_keys(name, ch.line_id)
        if a_info.key_kind != b_info.key_kind:
            ch.add("bundle", name, f"bundle {name}: signed with a {a_info.key_kind} key before, a {b_info.key_kind} "
                   "key now", field_="key_kind", before=a_info.key_kind, after=b_info.key_kind, direction=d,
                   train_type=t)
        fa = {f.name: f for f in a_info.files}
        fb = {f.name: f for f in b_info.files}

        parts, rows_changed, bytes_changed = [], 0, 0
        for m in sorted(set(fa) | set(fb)):
            x, y = fa.get(m), fb.get(m)
            if x and y and x.sha256 == y.sha256:
                continue
            tname = m.removesuffix(".parquet")
            # members whose digests the signed manifests vouch for, read a row group at a time
            nd = _rows_differing(a_members.get(m) if x else None, b_members.get(m) if y else None)
            rows_changed += nd
            bytes_changed += abs((y.size if y else 0) - (x.size if x else 0))
            parts.append(f"{tname} {nd} rows")
        key_note = " (signed with another key)" if a_info.key_id != b_info.key_id else ""
        if parts:
            what = f"{len(parts)} table{'s' if len(parts) != 1 else ''} changed: {', '.join(parts)}"
        else:
            fields = [label for f, label in MANIFEST_CONTENT if getattr(a_info, f) != getattr(b_info, f)]
            if not fields:  # the same content re-issued (build time, version, expiry): no change
                continue
            what = "no table changed, only the signed manifest's " + " and ".join(fields)
        ch.add("bundle", name, f"bundle {name}: {what}; {a_info.size_bytes} → {b_info.size_bytes} bytes{key_note}",
               field_="rows_differing", before=a_info.sha256, after=b_info.sha256, delta=float(rows_changed),
               direction=d, train_type=t)


def _same_bytes(a: Path, b: Path, chunk: int = 1 << 20) -> bool:
    """Two files hold the same bytes, read a chunk at a time: two runs' bundles that differ mostly differ early, in
    their signed manifests, so a network's bundles are not read whole to find it (nor cached by name, as
    :func:`filecmp.cmp` does: a bundle rewritten in the same tick of the clock would be taken as unchanged)."""
    if a.stat().st_size != b.stat().st_size:
        return False
    with open(a, "rb") as fa, open(b, "rb") as fb:
        while True:
            x, y = fa.read(chunk), fb.read(chunk)
            if x != y:
                return False
            if not x:
                return True


def _bundle_keys(name: str, line_id: str) -> tuple[str | None, str | None]:
    rest = name[len(line_id) + 1:].removesuffix(".pdb")
    d, _, t = rest.partition("_")
    return (d or None), (t or None)


def _pieces(x, skip: set = frozenset()):
    """A table's pieces: the table itself, or a Parquet member's row groups one at a time (but those in ``skip``)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    if isinstance(x, pa.Table):
        yield x
        return
    f = pq.ParquetFile(pa.BufferReader(x))
    for i in range(f.num_row_groups):
        if i not in skip:
            yield f.read_row_group(i)


def _group_digests(data: bytes) -> list[bytes]:
    """Each row group of a Parquet member by the digest of its bytes (its column chunks, as written) and the file's
    schema: two row groups with the same digest hold the same rows."""
    import hashlib

    import pyarrow as pa
    import pyarrow.parquet as pq

    md = pq.ParquetFile(pa.BufferReader(data)).metadata
    schema = repr([(c.path, c.physical_type, str(c.logical_type), c.max_definition_level, c.max_repetition_level)
                   for c in md.schema]).encode()
    out = []
    for i in range(md.num_row_groups):
        rg, h = md.row_group(i), hashlib.sha256(schema)
        for j in range(rg.num_columns):
            c = rg.column(j)
            start = c.dictionary_page_offset if c.has_dictionary_page and c.dictionary_page_offset else \
                c.data_page_offset
            h.update(memoryview(data)[start:start + c.total_compressed_size])
        out.append(h.digest())
    return out


def _same_groups(a: bytes, b: bytes) -> tuple[set, set]:
    """The row groups of ``a`` and of ``b`` that the other has byte for byte (as multisets): their rows cancel out."""
    da, db = _group_digests(a), _group_digests(b)
    left: dict[bytes, list[int]] = {}
    for j, d in enumerate(db):
        left.setdefault(d, []).append(j)
    sa, sb = set(), set()
    for i, d in enumerate(da):
        if left.get(d):
            sa.add(i)
            sb.add(left[d].pop())
    return sa, sb


def _rows_differing(a, b) -> int:
    """Rows in one table and not the other (as multisets of whole rows); each a table, a Parquet member's bytes (read
    a row group at a time: a bundle's table (d) on a network has millions of rows), or None."""
    import numpy as np
    import pandas as pd
    import pyarrow as pa
    import pyarrow.parquet as pq

    def rows(x) -> int:
        if x is None:
            return 0
        return x.num_rows if isinstance(x, pa.Table) else pq.read_metadata(pa.BufferReader(x)).num_rows

    if a is None or b is None:
        return rows(a) + rows(b)

    def hashes(x, skip) -> np.ndarray:  # one 64-bit hash per row, a row's alone (the same in any piece)
        got = [pd.util.hash_pandas_object(p.to_pandas(), index=False).to_numpy() for p in _pieces(x, skip)]
        return np.concatenate(got) if got else np.zeros(0, dtype=np.uint64)

    # two members of bundles built from datasets that an edit touched in places: most row groups (a dataset file
    # each) are the same bytes in both, and only the others' rows are compared
    skip = _same_groups(a, b) if not isinstance(a, pa.Table) and not isinstance(b, pa.Table) else (set(), set())
    try:  # counted as sorted arrays
        ha, hb = hashes(a, skip[0]), hashes(b, skip[1])
    except TypeError:  # list columns cannot be hashed by pandas
        from collections import Counter

        from planner.report.changes import _canon

        whole = [x if isinstance(x, pa.Table) else pq.read_table(pa.BufferReader(x)) for x in (a, b)]
        ca, cb = (Counter(tuple(_canon(v) for v in r.values()) for r in t.to_pylist()) for t in whole)
        return sum(((ca - cb) + (cb - ca)).values())
    va, na = np.unique(ha, return_counts=True)
    vb, nb = np.unique(hb, return_counts=True)
    if not len(va) or not len(vb):
        return len(ha) + len(hb)
    at = np.minimum(np.searchsorted(vb, va), len(vb) - 1)  # each value of a, where b has it if it does
    both = vb[at] == va
    common = int(np.minimum(na[both], nb[at[both]]).sum())  # rows the two have alike, counted once in each
    return len(ha) + len(hb) - 2 * common


# ---------------------------------------------------------------------------
# The comparison
# ---------------------------------------------------------------------------
