"""Fixtures shared by several test modules, and the property tests' profile."""
from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import settings

# `make test` and CI run the property tests on a fixed sequence of examples (derandomize), so a run
# is reproducible and a red run is never a roll of the dice; `HYPOTHESIS_PROFILE=explore make test`
# searches new random examples (what it finds becomes an explicit test, as in test_stopping_props).
settings.register_profile("repeatable", derandomize=True, database=None)
settings.register_profile("explore")
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "repeatable"))


@pytest.fixture(scope="module")
def keys(tmp_path_factory):
    """A fresh Ed25519 key pair: (private key path, public key path, loaded private key)."""
    from planner.bundle import signing

    d = tmp_path_factory.mktemp("keys")
    priv, pub = signing.generate_keypair(d)
    return priv, pub, signing.load_private_key(priv)


SAMPLE = Path(__file__).resolve().parents[1] / "lines" / "sample"
"""The bundled sample line (committed, with lines/sample/build.py that makes it)."""


@pytest.fixture(scope="session")
def sample_dir():
    """The sample line's folder (the test is skipped when it is not built)."""
    if not (SAMPLE / "line.parquet").exists():
        pytest.skip("lines/sample is not built yet (python lines/sample/build.py)")
    return SAMPLE


@pytest.fixture(scope="session")
def sample_line(sample_dir):
    """The sample line, loaded once per test session."""
    import planner

    return planner.load_line(sample_dir)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """The test line of ``linedb.write_line_db`` (stations A, B, C; trains 101 and 202) without its track
    network, loaded once per module; a module that needs another tiny line defines its own."""
    from linedb import write_line_db
    from planner import load_line

    folder = tmp_path_factory.mktemp("line") / "tiny"
    write_line_db(folder, nodes=None, edges=None)
    return load_line(folder)
