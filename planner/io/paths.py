"""Ids that become file names or partition values: one rule, checked where a path is built.

Line ids, train types, station codes and run ids name folders, files and hive
partitions. Validation refuses bad ones (:mod:`planner.line.rules`), and every
writer checks again with :func:`check_path_id` where it builds the path, because
a line built in memory never passed the validator.
"""
from __future__ import annotations

import re

from planner.errors import InputError


PATH_ID_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")
"""Ids that become file names or partition values (module doc): 1-64 of A-Z a-z 0-9 . _ -, first alphanumeric."""


PATH_ID_RULE = "use 1-64 letters, digits, '.', '_' or '-', starting with a letter or digit"
"""The rule in words, for messages."""


def is_path_id(value: object) -> bool:
    """True when ``value`` can name a file or partition (:data:`PATH_ID_RE`)."""
    return isinstance(value, str) and PATH_ID_RE.fullmatch(value) is not None


def check_path_id(value: object, what: str) -> str:
    """``value`` if it can name a file or partition, else an :class:`~planner.errors.InputError` line.

    Writers call it where they build a path, even though validation refused bad
    ids already: a line built in memory does not pass the validator.
    """
    if not is_path_id(value):
        raise InputError(f"{what} {value!r} cannot name a file or partition: {PATH_ID_RULE}")
    return value  # type: ignore[return-value]
