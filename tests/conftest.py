"""Fixtures shared by several test modules."""
from __future__ import annotations

import pytest


@pytest.fixture(scope="module")
def keys(tmp_path_factory):
    """A fresh Ed25519 key pair: (private key path, public key path, loaded private key)."""
    from planner.bundle import signing

    d = tmp_path_factory.mktemp("keys")
    priv, pub = signing.generate_keypair(d)
    return priv, pub, signing.load_private_key(priv)
