"""Tables and files: write results whole or not at all.

``write_table`` picks CSV or Parquet from the file suffix. Every writer here goes through
:func:`atomic_path`: it writes a temporary file in the destination folder and moves it into
place with ``os.replace``, so a reader never sees a half-written file and an interrupted run
leaves the old file (if any) untouched.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from .errors import InputError, design_error

TABLE_SUFFIXES = (".csv", ".parquet")

logger = logging.getLogger(__name__)


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
