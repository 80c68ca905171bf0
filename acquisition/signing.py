"""MAVLink 2 signing keys: from a key file, or the environment variable ``SFAP_SIGNING_KEY``.

A key is 32 bytes; a file holds them raw, or 64 hex digits, or a passphrase that becomes
SHA-256(passphrase) as MAVProxy makes it. :class:`acquisition.link.Link` signs with the key.
"""

from __future__ import annotations

import hashlib
import os
import re
from pathlib import Path

from .link_port import LinkInputError

SIGNING_KEY_ENV = "SFAP_SIGNING_KEY"


def signing_key_from_text(text: str) -> bytes:
    """A key from text: 64 hex digits are the key itself; anything else is a passphrase.

    A passphrase becomes SHA-256(passphrase, UTF-8), as MAVProxy's ``signing setup`` does, so
    the same passphrase given to MAVProxy or Mission Planner gives the same key.
    """
    stripped = text.strip()
    if not stripped:
        raise LinkInputError("the signing key is empty; give 64 hex digits or a passphrase")
    if re.fullmatch(r"[0-9A-Fa-f]{64}", stripped):
        return bytes.fromhex(stripped)
    return hashlib.sha256(stripped.encode("utf-8")).digest()


def load_signing_key(
    path: str | os.PathLike[str] | None = None, *, environ: dict[str, str] | None = None
) -> bytes | None:
    """The 32-byte MAVLink 2 signing key from ``path``, else from ``$SFAP_SIGNING_KEY``, else None.

    A key file holds either exactly 32 raw bytes, or 64 hex digits, or a passphrase (one line,
    hashed with SHA-256 as MAVProxy does). The environment variable holds 64 hex digits or a
    passphrase.
    """
    if path is not None:
        file = Path(path)
        try:
            data = file.read_bytes()
        except OSError as error:
            raise LinkInputError(
                f"cannot read the signing key file {file}: {error.strerror or error}"
            ) from error
        # 32 bytes that are all printable ASCII are far likelier a passphrase than a random key
        if len(data) == 32 and not re.fullmatch(rb"[ -~]{32}", data):
            return data
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError as error:
            raise LinkInputError(
                f"signing key file {file} holds {len(data)} bytes that are not text; a raw key "
                f"must be exactly 32 bytes (or write 64 hex digits or a passphrase)"
            ) from error
        return signing_key_from_text(text)
    env = os.environ if environ is None else environ
    value = env.get(SIGNING_KEY_ENV)
    if value:
        return signing_key_from_text(value)
    return None
