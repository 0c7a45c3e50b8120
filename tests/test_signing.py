"""Ed25519 key files and signatures (planner.bundle.signing)."""
from __future__ import annotations

import os
import stat

import pytest
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey
from cryptography.hazmat.primitives.asymmetric.rsa import generate_private_key

from planner.bundle import signing
from planner.errors import BundleError


def test_generate_writes_owner_only_private_key_and_public_key(tmp_path):
    old = os.umask(0)  # even with a permissive umask the private key must be 0600
    try:
        priv, pub = signing.generate_keypair(tmp_path / "keys")
    finally:
        os.umask(old)
    assert priv.name == "signing_key.pem" and pub.name == "signing_key.pub.pem"
    assert stat.S_IMODE(priv.stat().st_mode) == 0o600
    assert stat.S_IMODE(pub.stat().st_mode) == 0o644
    assert b"BEGIN PRIVATE KEY" in priv.read_bytes()  # PKCS#8, unencrypted
    assert b"BEGIN PUBLIC KEY" in pub.read_bytes()
    key, pubkey = signing.load_private_key(priv), signing.load_public_key(pub)
    raw = lambda k: k.public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)  # noqa: E731
    assert raw(key.public_key()) == raw(pubkey)


def test_private_key_is_created_with_0600_from_the_start(tmp_path, monkeypatch):
    """The mode is given to os.open itself (O_EXCL), not set after writing."""
    calls = []
    real_open = os.open

    def spy(path, flags, mode=0o777, *a, **kw):
        calls.append((os.fspath(path), flags, mode))
        return real_open(path, flags, mode, *a, **kw)

    monkeypatch.setattr(os, "open", spy)
    signing.generate_keypair(tmp_path)
    (path, flags, mode), = [c for c in calls if c[0].endswith("signing_key.pem")]
    assert flags & os.O_EXCL and flags & os.O_CREAT
    assert mode == 0o600


def test_generate_refuses_to_overwrite(tmp_path):
    priv, pub = signing.generate_keypair(tmp_path)
    before = priv.read_bytes(), pub.read_bytes()
    with pytest.raises(BundleError, match="refusing to overwrite"):
        signing.generate_keypair(tmp_path)
    pub.unlink()  # a lone private key is still not overwritten
    with pytest.raises(BundleError, match="refusing to overwrite"):
        signing.generate_keypair(tmp_path)
    assert priv.read_bytes() == before[0]


def test_generate_refuses_a_planted_symlink(tmp_path):
    target = tmp_path / "victim"
    target.write_bytes(b"keep")
    (tmp_path / "k").mkdir()
    (tmp_path / "k" / "signing_key.pem").symlink_to(target)
    with pytest.raises(BundleError):
        signing.generate_keypair(tmp_path / "k")
    assert target.read_bytes() == b"keep"


def test_sign_is_deterministic_and_verifies(tmp_path):
    priv, pub = signing.generate_keypair(tmp_path)
    key = signing.load_private_key(priv)
    s1, s2 = signing.sign(key, b"manifest"), signing.sign(key, b"manifest")
    assert s1 == s2 and len(s1) == signing.SIGNATURE_BYTES  # RFC 8032: no random nonce
    signing.verify(signing.load_public_key(pub), b"manifest", s1)


@pytest.mark.parametrize("change", ["data", "sig", "key", "short"])
def test_verify_refuses(tmp_path, change):
    priv, pub = signing.generate_keypair(tmp_path)
    key, pubkey = signing.load_private_key(priv), signing.load_public_key(pub)
    data, sig = b"manifest", signing.sign(key, b"manifest")
    if change == "data":
        data = b"manifesT"
    elif change == "sig":
        sig = bytes([sig[0] ^ 1]) + sig[1:]
    elif change == "key":
        pubkey = Ed25519PrivateKey.generate().public_key()
    else:
        sig = sig[:-1]
    with pytest.raises(BundleError):
        signing.verify(pubkey, data, sig)


def test_load_private_key_refuses_readable_by_others(tmp_path):
    priv, _ = signing.generate_keypair(tmp_path)
    os.chmod(priv, 0o644)
    with pytest.raises(BundleError, match="chmod 600"):
        signing.load_private_key(priv)


def test_load_keys_refuse_wrong_kinds(tmp_path):
    rsa = generate_private_key(public_exponent=65537, key_size=2048)
    p = tmp_path / "rsa.pem"
    p.write_bytes(rsa.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                    serialization.NoEncryption()))
    os.chmod(p, 0o600)
    with pytest.raises(BundleError, match="not Ed25519"):
        signing.load_private_key(p)
    q = tmp_path / "rsa.pub.pem"
    q.write_bytes(rsa.public_key().public_bytes(serialization.Encoding.PEM,
                                                serialization.PublicFormat.SubjectPublicKeyInfo))
    with pytest.raises(BundleError, match="not Ed25519"):
        signing.load_public_key(q)
    junk = tmp_path / "junk.pem"
    junk.write_bytes(b"hello")
    with pytest.raises(BundleError):
        signing.load_public_key(junk)
    with pytest.raises(BundleError, match="not found"):
        signing.load_public_key(tmp_path / "nope.pem")
