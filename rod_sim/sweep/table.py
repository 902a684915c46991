"""Sweep result tables: rows (plain dicts, one per run) to CSV or Parquet and back.

The format follows the file extension: ``.csv`` (the ``csv`` module; floats written with
``repr`` so they read back exactly, NaN as ``nan``) or ``.parquet`` (pyarrow, the ``sweep``
extra; the spec settings are kept in the schema metadata under ``rod_sim.sweep``).
"""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path

FORMATS = (".csv", ".parquet")
_STRING_COLUMNS = {"model", "status"}


def table_format(path: str | Path) -> str:
    """'.csv' or '.parquet' from the file name (ValueError naming --out otherwise)."""
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        raise ValueError(f"--out: {path} must end in .csv or .parquet")
    return suffix


def columns_of(rows: list[dict], columns: list[str] | None = None) -> list[str]:
    """The column order: ``columns`` if given, else the keys of the first row."""
    if columns is not None:
        return list(columns)
    return list(rows[0]) if rows else []


def write_table(rows: list[dict], path: str | Path, columns: list[str],
                metadata: dict | None = None) -> None:
    """Write ``rows`` (in the given order) with ``columns`` to ``path`` (.csv or .parquet)."""
    if table_format(path) == ".csv":
        with open(path, "w", newline="", encoding="utf-8") as f:
            writer = csv.writer(f)
            writer.writerow(columns)
            for row in rows:
                writer.writerow([_csv_cell(row.get(c)) for c in columns])
        return
    import pyarrow as pa
    import pyarrow.parquet as pq

    arrays = {}
    for c in columns:
        values = [row.get(c) for row in rows]
        if c in _STRING_COLUMNS or any(isinstance(v, str) for v in values):
            arrays[c] = pa.array([None if v is None else str(v) for v in values], pa.string())
        elif values and all(isinstance(v, int) and not isinstance(v, bool) for v in values):
            arrays[c] = pa.array(values, pa.int64())
        else:
            arrays[c] = pa.array([math.nan if v is None else float(v) for v in values],
                                 pa.float64())
    table = pa.table(arrays)
    if metadata:
        table = table.replace_schema_metadata({"rod_sim.sweep": json.dumps(metadata)})
    pq.write_table(table, path)


def _csv_cell(v):
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)
    return v


def _csv_value(text: str):
    if text == "":
        return None
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return text


def read_table(path: str | Path) -> list[dict]:
    """Rows of a table written by :func:`write_table` (numbers as int/float, text as str)."""
    if table_format(path) == ".csv":
        with open(path, newline="", encoding="utf-8") as f:
            reader = csv.DictReader(f)
            return [{k: (v if k in _STRING_COLUMNS else _csv_value(v)) for k, v in r.items()}
                    for r in reader]
    import pyarrow.parquet as pq

    return pq.read_table(path).to_pylist()


def read_metadata(path: str | Path) -> dict:
    """The spec settings stored with a Parquet table ({} for CSV or none stored)."""
    if table_format(path) != ".parquet":
        return {}
    import pyarrow.parquet as pq

    meta = pq.read_schema(path).metadata or {}
    raw = meta.get(b"rod_sim.sweep")
    return json.loads(raw) if raw else {}
