"""The safe reader of TOML input files (scenarios, DP problems, sweeps): only a regular file, of
bounded size, UTF-8 without NUL, valid TOML, every value finite and bounded. Every command that
reads a file goes through :func:`read_toml`; :mod:`downhole.scenario` re-exports it. It sits
below the scenario package so that the control and core layers can read files without importing
scenario code (see ``docs/scenarios.md``, "Limits")."""

from __future__ import annotations

import tomllib
from pathlib import Path

from downhole.errors import ScenarioError

__all__ = [
    "MAX_DEPTH",
    "MAX_FILE_BYTES",
    "MAX_INTEGER",
    "MAX_LIST_LENGTH",
    "MAX_NUMBER",
    "MAX_STRING_LENGTH",
    "check_values",
    "parse_toml_text",
    "read_regular_file",
    "read_scenario_text",
    "read_toml",
]


#: Largest scenario file read (bytes); a scenario is a few kB.
MAX_FILE_BYTES = 1 << 20
#: Longest string value in a scenario file (characters).
MAX_STRING_LENGTH = 4096
#: Longest list in a scenario file (entries: survey stations, profile breakpoints, ...).
MAX_LIST_LENGTH = 100_000
#: Deepest nesting of tables and lists.
MAX_DEPTH = 16
#: Largest magnitude of a bare number (SI); physical fields have narrower ranges
#: (:data:`downhole.units.RANGES`).
MAX_NUMBER = 1e15
#: Largest magnitude of an integer (seeds, counts, ports).
MAX_INTEGER = 2**63 - 1


def read_scenario_text(path: str | Path) -> tuple[str, str]:
    """Read a scenario file's text safely: ``(text, source)``.

    Only a regular file is opened (a directory, a FIFO, a device or a socket is refused before
    opening, so nothing blocks), at most :data:`MAX_FILE_BYTES` are read, and the bytes must be
    UTF-8 without NUL characters.

    Raises
    ------
    ScenarioError
        Naming the file and what is wrong with it.
    """
    path = Path(path)
    source = str(path)
    raw = read_regular_file(path, MAX_FILE_BYTES, "a scenario (a regular TOML file of a few kB)")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise ScenarioError(source, "", f"not UTF-8 text: byte 0x{raw[exc.start]:02x} at "
                            f"offset {exc.start} (line {line}); save the file as UTF-8"
                            ) from None
    if "\x00" in text:
        line = text[:text.index("\x00")].count("\n") + 1
        raise ScenarioError(source, "", f"NUL character at line {line}; a scenario is text")
    return text, source


def read_regular_file(path: str | Path, max_bytes: int, expected: str) -> bytes:
    """Read a data file's bytes safely: only a regular file (a directory, a FIFO, a device such
    as ``/dev/zero`` or a socket is refused before it is opened, so nothing blocks or reads
    without end), at most ``max_bytes`` of it.

    Parameters
    ----------
    path : str or Path
        The file.
    max_bytes : int
        Largest size accepted.
    expected : str
        What the file should be, for messages (e.g. ``"a saved DHP controller (.json)"``).

    Raises
    ------
    ScenarioError
        Naming the file and what is wrong with it.
    """
    import os
    import stat

    source = str(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise ScenarioError(source, "", "file not found") from None
    except (OSError, ValueError) as exc:
        raise ScenarioError(source, "", f"cannot read the file ({exc})") from None
    if not stat.S_ISREG(st.st_mode):
        kind = ("a directory" if stat.S_ISDIR(st.st_mode) else
                "a FIFO (named pipe)" if stat.S_ISFIFO(st.st_mode) else
                "a socket" if stat.S_ISSOCK(st.st_mode) else "a device or special file")
        raise ScenarioError(source, "", f"is {kind}; expected {expected}")
    if st.st_size > max_bytes:
        raise ScenarioError(source, "", f"file of {st.st_size} bytes; {expected} is at most "
                            f"{max_bytes} bytes")
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise ScenarioError(source, "", f"cannot read the file ({exc.strerror})") from None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):  # replaced between stat and open
            raise ScenarioError(source, "", f"is not a regular file; expected {expected}")
        with os.fdopen(fd, "rb", closefd=False) as fh:
            raw = fh.read(max_bytes + 1)
    except OSError as exc:
        raise ScenarioError(source, "", f"cannot read the file ({exc.strerror})") from None
    finally:
        os.close(fd)
    if len(raw) > max_bytes:
        raise ScenarioError(source, "", f"file larger than {max_bytes} bytes; {expected} is "
                            "smaller")
    return raw


def parse_toml_text(text: str, source: str) -> dict:
    """Parse TOML text and check every value (:func:`check_values`).

    Parameters
    ----------
    text : str
        The file's text.
    source : str
        The file name for messages.

    Returns
    -------
    dict
        The parsed data.

    Raises
    ------
    ScenarioError
        Not valid TOML (also a 5000-digit integer or nesting too deep for the parser), or a
        value no field accepts.
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(source, "", f"not valid TOML: {exc}") from None
    except (ValueError, RecursionError, OverflowError) as exc:  # e.g. a 5000-digit integer
        msg = str(exc).split(";")[0]
        raise ScenarioError(source, "", f"not valid TOML: {msg}") from None
    check_values(data, source)
    return data


def read_toml(path: str | Path) -> tuple[dict, str, str]:
    """Read, parse and check a TOML scenario file.

    Every command that reads a scenario goes through here (:func:`read_scenario_text`, then
    :func:`parse_toml_text`), so hostile input gets one error naming the file and the field.

    Parameters
    ----------
    path : str or Path
        The scenario file.

    Returns
    -------
    (dict, str, str)
        The parsed data, the source name (the path as given) and the file's text.

    Raises
    ------
    ScenarioError
        Not a regular file, too large, not UTF-8, NUL characters, not TOML, or a value no field
        accepts (:func:`check_values`).
    """
    text, source = read_scenario_text(path)
    return parse_toml_text(text, source), source, text


def check_values(data, source: str, prefix: str = "") -> None:
    """Reject values no scenario field accepts, naming the dotted field.

    Parameters
    ----------
    data : dict
        A parsed scenario (nested dicts, lists and scalars).
    source : str
        The file name for messages.
    prefix : str
        Dotted path of ``data`` inside the scenario (empty for the whole file).

    Raises
    ------
    ScenarioError
        Non-finite numbers (``inf``, ``nan``), numbers beyond :data:`MAX_NUMBER` (integers
        beyond :data:`MAX_INTEGER`), strings longer than :data:`MAX_STRING_LENGTH` or with
        control characters (NUL, ...), lists longer than :data:`MAX_LIST_LENGTH`, nesting
        deeper than :data:`MAX_DEPTH`. Physical ranges are checked per field later
        (:mod:`downhole.units`).
    """
    import math

    stack = [(prefix, data, 0)]
    while stack:
        field, value, depth = stack.pop()
        where = field or "<top>"
        if depth > MAX_DEPTH:
            raise ScenarioError(source, where, f"nested deeper than {MAX_DEPTH} levels")
        if isinstance(value, bool):
            continue
        if isinstance(value, int):
            if abs(value) > MAX_INTEGER:
                raise ScenarioError(source, where, f"integer out of range (|value| must be at "
                                    f"most {MAX_INTEGER})")
        elif isinstance(value, float):
            if not math.isfinite(value):
                raise ScenarioError(source, where, f"expected a finite number, got {value!r}")
            if abs(value) > MAX_NUMBER:
                raise ScenarioError(source, where, f"number {value:g} out of range (|value| "
                                    f"must be at most {MAX_NUMBER:g}; see docs/scenarios.md)")
        elif isinstance(value, str):
            if len(value) > MAX_STRING_LENGTH:
                raise ScenarioError(source, where, f"string of {len(value)} characters; at most "
                                    f"{MAX_STRING_LENGTH} are accepted")
            bad = next((c for c in value if (ord(c) < 32 and c not in "\t\n\r")
                        or ord(c) == 127), None)
            if bad is not None:
                raise ScenarioError(source, where, f"control character {bad!r} in a string")
            _check_numeric_string(value, source, where)
        elif isinstance(value, dict):
            for k, v in value.items():
                ks = str(k)
                if len(ks) > 128 or any(ord(c) < 32 or ord(c) == 127 for c in ks):
                    raise ScenarioError(source, where, f"invalid key {ks[:40]!r}")
                stack.append((f"{field}.{ks}" if field else ks, v, depth + 1))
        elif isinstance(value, list):
            if len(value) > MAX_LIST_LENGTH:
                raise ScenarioError(source, where, f"list of {len(value)} entries; at most "
                                    f"{MAX_LIST_LENGTH} are accepted")
            for i, v in enumerate(value):
                stack.append((f"{field}.{i}" if field else str(i), v, depth + 1))
        # TOML dates and times pass through; the schemas reject them where a number is expected


def _check_numeric_string(value: str, source: str, where: str) -> None:
    """A string that is a bare number ("1e300", "nan", "inf") reaches plain float fields through
    pydantic's coercion: hold it to the same rules as a number."""
    import math

    text = value.strip()
    if not text or len(text) > 40 or not (text[0].isdigit() or text[0] in "+-.iInN"):
        return
    try:
        number = float(text)
    except ValueError:
        return
    if not math.isfinite(number):
        raise ScenarioError(source, where, f"expected a finite number, got {value!r}")
    if abs(number) > MAX_NUMBER:
        raise ScenarioError(source, where, f"number {value!r} out of range (|value| must be at "
                            f"most {MAX_NUMBER:g}; see docs/scenarios.md)")
