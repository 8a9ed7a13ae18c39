"""Tables and files: write results whole or not at all.

``write_table`` picks CSV or Parquet from the file suffix. Every writer here goes through
:func:`atomic_path`: it writes a temporary file in the destination folder and moves it into
place with ``os.replace``, so a reader never sees a half-written file and an interrupted run
leaves the old file (if any) untouched.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from .errors import InputError, design_error

TABLE_SUFFIXES = (".csv", ".parquet")


def check_table_path(path: str | os.PathLike) -> Path:
    """The path as a Path if its suffix is a table format softrod writes, else InputError.

    Call it before a long computation so a typo in the output name fails at once.
    """
    path = Path(path)
    if path.suffix.lower() not in TABLE_SUFFIXES:
        raise design_error(
            "path",
            str(path),
            f"unknown table format {path.suffix or '(no suffix)'!r}: the file name must end in "
            f"one of {', '.join(TABLE_SUFFIXES)}",
            InputError,
        )
    _check_folder(path)
    return path


def _check_folder(path: Path) -> None:
    folder = path.parent
    if not folder.is_dir():
        raise design_error("path", str(path), f"folder {str(folder)!r} does not exist", InputError)


def _default_mode() -> int:
    # mkstemp creates files readable by the owner only; give the final file the mode a plain
    # open() would (0o666 minus the umask). Reading the umask means setting it, so restore it.
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success move it onto ``path``.

    On an exception the temporary file is removed and ``path`` is left as it was.
    """
    path = Path(path)
    _check_folder(path)
    fd, tmp_name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        os.chmod(tmp, _default_mode())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def write_table(df, path: str | os.PathLike) -> Path:
    """Write a pandas DataFrame to ``path`` as CSV (``.csv``) or Parquet (``.parquet``).

    The file is written atomically (whole or not at all). Column names should carry their
    units (``p1_Pa``, ``x_mm``). Raises :class:`InputError` for any other suffix.
    Returns the path written.
    """
    path = check_table_path(path)
    with atomic_path(path) as tmp:
        if path.suffix.lower() == ".csv":
            df.to_csv(tmp, index=False)
        else:
            df.to_parquet(tmp, index=False, engine="pyarrow")
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
