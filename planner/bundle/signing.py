"""Ed25519 keys, signatures and their files, for signed on-board DB bundles.

A bundle's manifest is signed with an Ed25519 private key (RFC 8032). Ed25519
signatures are deterministic (no random nonce), so the same manifest and key
always give the same signature, which keeps bundle builds byte-reproducible.

Key files are PEM: the private key as unencrypted PKCS#8, readable by its owner
only (mode 0600, created with ``O_EXCL`` so it is never readable by others, not
even for an instant); the public key as SubjectPublicKeyInfo. The private key
never leaves this module except as a key object handed to :func:`sign`.

Example
-------
>>> priv, pub = generate_keypair(tmp_dir)            # doctest: +SKIP
>>> sig = sign(load_private_key(priv), b"manifest")  # doctest: +SKIP
>>> verify(load_public_key(pub), b"manifest", sig)   # doctest: +SKIP
"""
from __future__ import annotations

import hashlib
import os
import stat
from pathlib import Path

from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import (
    Ed25519PrivateKey,
    Ed25519PublicKey,
)

from planner.errors import BundleError

PRIVATE_KEY_NAME = "signing_key.pem"
PUBLIC_KEY_NAME = "signing_key.pub.pem"
ENV_SIGNING_KEY = "PLANNER_SIGNING_KEY"
"""Environment variable holding the *path* of the private key file (never the key itself)."""
SIGNATURE_BYTES = 64
"""Length of an Ed25519 signature [bytes] (RFC 8032 §5.1.6)."""
DEV_KEY_DIR = ".dev-key"
"""Folder (under a job's output root) of the development key ``planner run`` makes for test runs."""
DEV_MARKER_NAME = "DEVELOPMENT_KEY"
"""A file beside a development key naming its public key id: the mark travels with the key folder."""
_MAX_KEY_FILE_BYTES = 64 * 1024
"""A PEM Ed25519 key is ~120 bytes; anything much larger is not a key file."""


def generate_keypair(directory: str | os.PathLike, *, development: bool = False) -> tuple[Path, Path]:
    """Write a new Ed25519 key pair into ``directory``; refuse to overwrite.

    Parameters
    ----------
    directory : path
        Folder for ``signing_key.pem`` (PKCS#8 PEM, mode 0600) and
        ``signing_key.pub.pem`` (SubjectPublicKeyInfo PEM, mode 0644). Created
        (mode 0700) if missing.
    development : bool
        A key for test runs: a ``DEVELOPMENT_KEY`` file beside it names its public key id, so
        that :func:`is_development_key` recognises it wherever it is used.

    Returns
    -------
    (private_path, public_path)

    Raises
    ------
    BundleError
        If either file already exists (an existing key is never replaced).
    """
    d = Path(directory)
    d.mkdir(mode=0o700, parents=True, exist_ok=True)
    priv_path, pub_path = d / PRIVATE_KEY_NAME, d / PUBLIC_KEY_NAME
    for p in (priv_path, pub_path):
        if os.path.lexists(p):
            raise BundleError(f"{p} already exists; refusing to overwrite a key (choose another folder)")
    key = Ed25519PrivateKey.generate()
    priv_pem = key.private_bytes(
        serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()
    )
    pub_pem = key.public_key().public_bytes(
        serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo
    )
    _write_new(priv_path, priv_pem, 0o600)
    try:
        _write_new(pub_path, pub_pem, 0o644)
    except BaseException:
        # A private key without its public half is useless and a needless secret on disk.
        priv_path.unlink(missing_ok=True)
        raise
    if development:
        _write_new(d / DEV_MARKER_NAME, (public_key_id(key.public_key()) + "\n").encode(), 0o644)
    return priv_path, pub_path


def is_development_key(private_key_path: str | os.PathLike) -> bool:
    """Whether a private key file is a development key (made for test runs, never for service).

    It is when it lies in a ``.dev-key`` folder (where ``planner run`` makes one) or when a
    ``DEVELOPMENT_KEY`` file beside it names its public key id (:func:`generate_keypair` with
    ``development=True``), so a development key copied elsewhere keeps its mark.
    """
    p = Path(private_key_path).resolve()
    if p.parent.name == DEV_KEY_DIR:
        return True
    marker = p.parent / DEV_MARKER_NAME
    if not marker.is_file():
        return False
    try:
        return marker.read_text(encoding="ascii").strip() == public_key_id(load_private_key(p).public_key())
    except (OSError, UnicodeDecodeError, BundleError):
        return False


def _write_new(path: Path, data: bytes, mode: int) -> None:
    """Create ``path`` exclusively with ``mode`` from the first byte on, write, fsync."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0)
    try:
        fd = os.open(path, flags, mode)
    except FileExistsError:
        raise BundleError(f"{path} already exists; refusing to overwrite a key (choose another folder)") from None
    try:
        os.fchmod(fd, mode)  # the umask may have removed bits we want (0644 for the public key)
        view = memoryview(data)
        while view:
            view = view[os.write(fd, view):]
        os.fsync(fd)
    except BaseException:
        os.close(fd)
        path.unlink(missing_ok=True)
        raise
    os.close(fd)


def _read_key_file(path: str | os.PathLike, what: str) -> bytes:
    p = Path(path)
    try:
        st = p.stat()
    except FileNotFoundError:
        raise BundleError(f"{what} {p} not found; give an existing key file") from None
    if not stat.S_ISREG(st.st_mode):
        raise BundleError(f"{what} {p} is not a regular file")
    if st.st_size > _MAX_KEY_FILE_BYTES:
        raise BundleError(f"{what} {p} is {st.st_size} bytes, too large for an Ed25519 PEM key")
    return p.read_bytes()


def load_private_key(path: str | os.PathLike) -> Ed25519PrivateKey:
    """Load an unencrypted PKCS#8 PEM Ed25519 private key.

    Refuses a key file that group or others may read (like OpenSSH does): a
    signing key others can read is no proof of origin.
    """
    p = Path(path)
    data = _read_key_file(p, "private key")
    mode = stat.S_IMODE(p.stat().st_mode)
    if mode & 0o077:
        raise BundleError(f"private key {p} has mode {mode:04o}, readable by others; run: chmod 600 {p}")
    try:
        key = serialization.load_pem_private_key(data, password=None)
    except (ValueError, TypeError) as e:
        raise BundleError(f"private key {p} is not an unencrypted PEM private key ({e})") from None
    if not isinstance(key, Ed25519PrivateKey):
        raise BundleError(f"private key {p} is a {type(key).__name__}, not Ed25519; run `planner keys generate DIR`")
    return key


def load_public_key(key: str | os.PathLike | bytes | Ed25519PublicKey) -> Ed25519PublicKey:
    """An Ed25519 public key from a PEM file path, PEM bytes, 32 raw bytes or a key object."""
    if isinstance(key, Ed25519PublicKey):
        return key
    if isinstance(key, (bytes, bytearray)):
        data, where = bytes(key), "public key"
        if len(data) == 32:
            return Ed25519PublicKey.from_public_bytes(data)
    else:
        data, where = _read_key_file(key, "public key"), f"public key {key}"
    try:
        pub = serialization.load_pem_public_key(data)
    except (ValueError, TypeError) as e:
        raise BundleError(f"{where} is not a PEM public key ({e})") from None
    if not isinstance(pub, Ed25519PublicKey):
        raise BundleError(f"{where} is a {type(pub).__name__}, not Ed25519")
    return pub


def public_key_id(key: Ed25519PublicKey) -> str:
    """SHA-256 (hex) of the 32 raw public-key bytes: names the key in a manifest."""
    raw = key.public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)
    return hashlib.sha256(raw).hexdigest()


def sign(key: Ed25519PrivateKey, data: bytes) -> bytes:
    """Ed25519 signature of ``data`` (64 bytes, deterministic: RFC 8032 §5.1.6)."""
    return key.sign(data)


def verify(key: Ed25519PublicKey, data: bytes, signature: bytes) -> None:
    """Check an Ed25519 signature; raise :class:`BundleError` if it does not match."""
    if len(signature) != SIGNATURE_BYTES:
        raise BundleError(f"signature is {len(signature)} bytes, expected {SIGNATURE_BYTES}")
    try:
        key.verify(signature, data)
    except InvalidSignature:
        raise BundleError("signature does not match: wrong public key, or the bundle was altered") from None
