"""Tables and files: write results whole or not at all.

``write_table`` picks CSV or Parquet from the file suffix. Every writer of softrod (tables,
datasets, schedules, trajectories, designs, reports, figures, animations, JSON) goes through
:func:`atomic_path` (or :func:`staged_paths` for several files that belong together):

- the target's folder is checked first (it must exist and be writable), so a bad target
  fails at once, named by the target, before any computation;
- the data goes to a temporary file in the same folder, named
  ``.softrod-tmp-<pid>-<random>-<target name>``, which replaces the target in one
  ``os.replace`` when it is complete: a reader never sees a half-written file, and a failed
  write leaves the old file (if any) untouched;
- a temporary left behind by a process that was killed (SIGKILL, power loss) is removed by
  the next softrod write into that folder, once its process id no longer runs.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import re
import secrets
from collections.abc import Iterator, Mapping
from pathlib import Path

from .errors import InputError, design_error

TABLE_SUFFIXES = (".csv", ".parquet")

TMP_PREFIX = ".softrod-tmp-"
_TMP_NAME = re.compile(r"^\.softrod-tmp-(?P<pid>[0-9]{1,10})-[0-9a-f]{8}-")
_MAX_NAME = 255 - 40  # room for the temporary prefix within a file name's 255 bytes
logger = logging.getLogger(__name__)


def as_path(path: object, field: str = "path") -> Path:
    """``path`` (text or an os.PathLike) as a Path; InputError naming ``field`` for anything
    else (None, a number, bytes, a list), before any work."""
    if isinstance(path, bytes) or not isinstance(path, (str, os.PathLike)):
        raise design_error(
            field,
            type(path).__name__,
            "must be a file name: text or a path (pathlib.Path)",
            InputError,
        )
    if isinstance(path, str) and (not path.strip() or "\0" in path):
        raise design_error(field, path, "must be a non-empty file name", InputError)
    return Path(path)


def check_table_path(path: str | os.PathLike) -> Path:
    """The path as a Path if its suffix is a table format softrod writes and its folder
    exists and is writable, else InputError.

    Call it before a long computation so a typo in the output name fails at once.
    """
    path = as_path(path)
    if path.suffix.lower() not in TABLE_SUFFIXES:
        raise design_error(
            "path",
            str(path),
            f"unknown table format {path.suffix or '(no suffix)'!r}: the file name must end in "
            f"one of {', '.join(TABLE_SUFFIXES)}",
            InputError,
        )
    return check_target(path)


def is_file(path: str | os.PathLike) -> bool:
    """``Path(path).is_file()``, False where the file system cannot look the name up at all
    (a name too long for it: pathlib raises OSError for that on Python 3.11), so a reader
    says "no such file" instead of raising OSError."""
    try:
        return Path(path).is_file()
    except (OSError, ValueError):
        return False


def exists(path: str | os.PathLike) -> bool:
    """``Path(path).exists()``, False where the name cannot be looked up (see is_file)."""
    try:
        return Path(path).exists()
    except (OSError, ValueError):
        return False


def is_dir(path: str | os.PathLike) -> bool:
    """``Path(path).is_dir()``, False where the name cannot be looked up (see is_file)."""
    try:
        return Path(path).is_dir()
    except (OSError, ValueError):
        return False


def check_target(path: str | os.PathLike) -> Path:
    """``path`` as a Path if a file can be written there: its folder exists and is writable,
    and the path is not a folder. Otherwise InputError naming the target (not a temporary
    file), raised before any work."""
    path = as_path(path)
    folder = path.parent
    if not path.name or path.name in (".", ".."):
        raise design_error("path", str(path), "must name a file, not a folder", InputError)
    if len(os.fsencode(path.name)) > _MAX_NAME:
        raise design_error(
            "path", str(path), f"the file name is too long ({_MAX_NAME} bytes at most)", InputError
        )
    if not is_dir(folder):
        raise design_error("path", str(path), f"folder {str(folder)!r} does not exist", InputError)
    if not os.access(folder, os.W_OK | os.X_OK):
        raise design_error("path", str(path), f"folder {str(folder)!r} is not writable", InputError)
    if is_dir(path):
        raise design_error("path", str(path), "is a folder, not a file", InputError)
    return path


def _running(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, ValueError):
        return pid > 0  # it runs under another user (or the id is out of range: not ours)
    return True


def remove_stale_temporaries(folder: str | os.PathLike) -> list[Path]:
    """Remove the temporaries softrod left in ``folder`` whose process no longer runs (a
    writer that was killed); returns what was removed. Never raises."""
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        m = _TMP_NAME.match(entry.name)
        if m is None or _running(int(m["pid"])):
            continue
        with contextlib.suppress(OSError):
            os.unlink(entry.path)
            removed.append(Path(entry.path))
    return removed


def _temporary(path: Path) -> Path:
    """A new, empty file beside ``path`` that only this call owns (O_EXCL), created with
    the mode a plain open() would give (0o666 minus the umask)."""
    name = f"{TMP_PREFIX}{os.getpid()}-{secrets.token_hex(4)}-{path.name}"
    tmp = path.parent / name
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    except OSError as exc:  # named by the target, never by the temporary's name
        raise design_error(
            "path", str(path), f"cannot write there: {exc.strerror or exc}", InputError
        ) from None
    os.close(fd)
    return tmp


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` (it ends in ``path``'s name, so writers that
    choose the format from the suffix work); on success move it onto ``path``.

    The target is checked first (:func:`check_target`); stale temporaries of killed writers
    in the folder are removed. On an exception the temporary file is removed and ``path`` is
    left as it was.
    """
    path = check_target(path)
    remove_stale_temporaries(path.parent)
    tmp = _temporary(path)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


@contextlib.contextmanager
def staged_paths(paths: list[Path]) -> Iterator[list[Path]]:
    """Temporary paths for several outputs that belong together: when the block succeeds
    every file is moved into place, when it fails none is (and the temporaries go)."""
    paths = [check_target(p) for p in paths]
    for folder in {p.parent for p in paths}:
        remove_stale_temporaries(folder)
    staged: list[Path] = []
    try:
        for p in paths:
            staged.append(_temporary(p))
        yield staged
        for tmp, p in zip(staged, paths, strict=True):
            os.replace(tmp, p)
    except BaseException:
        for tmp in staged:
            with contextlib.suppress(OSError):
                tmp.unlink()
        raise


def _json_default(x):
    import numpy as np

    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, Path):
        return str(x)
    raise TypeError(f"{type(x).__name__} is not JSON serialisable")


def metadata_json(meta) -> str:
    """The metadata block as one line of standard JSON (numpy scalars and arrays, paths
    allowed; NaN and infinity are not JSON: an InputError)."""
    if not isinstance(meta, Mapping):
        raise design_error(
            "metadata", type(meta).__name__, "must be a mapping (a dict of names)", InputError
        )
    try:
        return json.dumps(dict(meta), default=_json_default, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise design_error(
            "metadata", dict(meta), f"must be JSON serialisable ({exc})", InputError
        ) from None


def write_table(df, path: str | os.PathLike, *, header: tuple[str, ...] = ()) -> Path:
    """Write a pandas DataFrame to ``path`` as CSV (``.csv``) or Parquet (``.parquet``).

    The file is written atomically (whole or not at all). Column names carry their units
    (``p0_kPa``, ``tip_x_mm``; docs/datasets.md). The metadata block
    ``df.attrs["softrod.metadata"]``, when there is one, goes into a ``# metadata: {...}``
    comment line of the CSV file (after the free-text ``header`` lines) or into the Parquet
    entry ``softrod.metadata``, where :func:`softrod.load_dataset` finds it. Raises
    :class:`InputError` for any other suffix. Returns the path written.
    """
    path = check_table_path(path)
    meta = df.attrs.get("softrod.metadata")
    text = None if meta is None else metadata_json(meta)
    with atomic_path(path) as tmp:
        if path.suffix.lower() == ".csv":
            with open(tmp, "w", encoding="utf-8", newline="") as fh:
                for line in header:
                    fh.write(f"# {line}\n")
                if text is not None:
                    fh.write(f"# metadata: {text}\n")
                df.to_csv(fh, index=False, lineterminator="\n")
        elif text is not None:
            write_parquet_with_metadata(df, tmp, text)
        else:
            df.to_parquet(tmp, index=False, engine="pyarrow")
    logger.debug("wrote %s (%d rows, %d columns)", path, len(df), len(df.columns))
    return path


def write_parquet_with_metadata(frame, path: str | os.PathLike, metadata_json: str) -> None:
    """Write ``frame`` to Parquet at ``path`` with ``metadata_json`` under the schema key
    ``softrod.metadata`` (how datasets and schedules keep their metadata in one file).
    Call it on the temporary path of :func:`atomic_path`."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.Table.from_pandas(frame, preserve_index=False)
    kv = dict(table.schema.metadata or {})
    kv[b"softrod.metadata"] = metadata_json.encode("utf-8")
    pq.write_table(table.replace_schema_metadata(kv), path)


MAX_FILE_BYTES = 2**31  # dataset, schedule and map files larger than this are refused unread


def read_text_file(path: Path) -> str:
    """A text file as str: UTF-8 (a byte-order mark allowed); anything else, such as a
    binary or UTF-16 file, is an InputError naming the file."""
    size = path.stat().st_size
    if size > MAX_FILE_BYTES:
        raise _fail("file", str(path), f"is too large ({size} bytes; at most {MAX_FILE_BYTES})")
    raw = path.read_bytes()
    if raw[:2] in (b"\xff\xfe", b"\xfe\xff"):
        raise _fail("file", str(path), "is UTF-16 text: save it as UTF-8 (CSV UTF-8)")
    if b"\0" in raw[:65536]:
        raise _fail("file", str(path), "is not a text file (it holds NUL bytes)")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise _fail(
            "file", str(path), f"is not UTF-8 text (byte {exc.start}, line {line}): save as UTF-8"
        ) from None


def _fail(field: str, value: object, rule: str) -> InputError:
    return design_error(field, value, rule, InputError)
