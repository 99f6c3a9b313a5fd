"""Atomic writes, Parquet files that carry their provenance, and content fingerprints."""

from __future__ import annotations

import contextlib
import hashlib
import importlib.util
import json
import os
import tempfile
from pathlib import Path
from typing import Any, Iterator, Mapping

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

META_KEY = b"dance3d"
# How a stage runs (not what it computes): never recorded in outputs nor in fingerprints, so
# switching executor or worker count redoes nothing and gives byte-identical files.
EXECUTION_KEYS = frozenset({"workers", "executor", "ray", "max_failure_ratio", "part_seconds"})  # how, not what


def _without_execution(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {k: v for k, v in value.items() if k not in EXECUTION_KEYS}
    return value


@contextlib.contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it into place only on success.

    A process killed half-way leaves at most a ``.tmp-*`` file, never a truncated output.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f".tmp-{path.stem}-", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600 files; outputs are ordinary files
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def remove_stale_temps(folder: Path) -> int:
    """Delete temp files left by a killed run; returns how many were removed."""
    if not folder.exists():
        return 0
    removed = 0
    for tmp in folder.glob(".tmp-*"):
        tmp.unlink(missing_ok=True)
        removed += 1
    return removed


def sha256_file(path: Path, chunk: int = 1 << 20) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(chunk):
            h.update(block)
    return h.hexdigest()


def fingerprint(*parts: Any) -> str:
    """A stable short hash of JSON-serialisable parts (inputs' hashes, params)."""
    blob = json.dumps([_without_execution(p) for p in parts], sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:20]


def code_fingerprint(*modules: Any) -> str:
    """A hash of the code of the modules that make an output: changed code redoes the items
    (DVC re-runs the stage when its code changes; this makes the stage redo its items too).
    Comments, docstrings and blank lines are not code: editing them redoes nothing.
    A module is given as itself or by its dotted name; a name is found without importing the
    module, so a stage with nothing to do need not load what its work imports."""
    h = hashlib.sha256()
    for module in modules:
        h.update(code_text(Path(_source_file(module)).read_text(encoding="utf-8")).encode())
    return h.hexdigest()[:16]


def code_text(source: str) -> str:
    """Python source without its comments, docstrings and blank lines, otherwise as written. Text,
    not an AST dump, so the same code gives the same text under every Python version; the AST only
    says where docstrings and string literals are (a ``#`` inside a string is code)."""
    import ast
    import re

    lines = source.splitlines()
    dropped: set[int] = set()  # 0-based lines that are a docstring, whole
    strings: dict[int, list[tuple[int, int]]] = {}  # 0-based line -> byte spans inside string literals
    for node in ast.walk(ast.parse(source)):
        body = getattr(node, "body", None)
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and body:
            first = body[0]
            if (isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant)
                    and isinstance(first.value.value, str)
                    and not lines[first.lineno - 1][:first.col_offset].strip()  # alone on its lines
                    and not lines[first.end_lineno - 1].encode()[first.end_col_offset:].strip()):
                dropped.update(range(first.lineno - 1, first.end_lineno))
        if isinstance(node, ast.JoinedStr) or (isinstance(node, ast.Constant) and isinstance(node.value, (str, bytes))):
            for row in range(node.lineno - 1, node.end_lineno):
                strings.setdefault(row, []).append((node.col_offset if row == node.lineno - 1 else 0,
                                                    node.end_col_offset if row == node.end_lineno - 1 else 1 << 30))
    kept = []
    for row, line in enumerate(lines):
        if row in dropped:
            continue
        if "#" in line:  # a comment starts at the first # outside every string (AST columns count bytes)
            raw = line.encode()
            hashes = (m.start() for m in re.finditer(b"#", raw))
            cut = next((i for i in hashes if not any(a <= i < b for a, b in strings.get(row, ()))), None)
            line = line if cut is None else raw[:cut].decode()
        if line.strip():
            kept.append(line.rstrip())
    return "\n".join(kept)


def _source_file(module: Any) -> str:
    if not isinstance(module, str):
        return module.__file__
    spec = importlib.util.find_spec(module)
    if spec is None or not spec.origin:
        raise ModuleNotFoundError(f"code_fingerprint: no module named {module!r}")
    return spec.origin


def write_parquet(
    table: pa.Table,
    path: Path,
    *,
    schema_version: int,
    params: Mapping[str, Any] | None = None,
    inputs: Mapping[str, str] | None = None,
    extra: Mapping[str, Any] | None = None,
    compression: str = "zstd",
    row_group_size: int | None = None,
) -> None:
    """Write ``table`` atomically with dance3d provenance in its key-value metadata."""
    meta = {
        "schema_version": schema_version,
        "params": _without_execution(dict(params or {})),
        "inputs": dict(inputs or {}),
        **dict(extra or {}),
    }
    existing = table.schema.metadata or {}
    # pandas metadata embeds nothing time-dependent, but drop it: the schema is ours.
    existing = {k: v for k, v in existing.items() if k != b"pandas"}
    schema_meta = {**existing, META_KEY: json.dumps(meta, sort_keys=True, default=str).encode()}
    table = table.replace_schema_metadata(schema_meta)
    floats, others = _leaf_columns(table.schema)
    with atomic_path(path) as tmp:
        # Floats byte-stream split, without a dictionary: motion is smooth, so the split bytes repeat
        # and compress about a third smaller (lossless; every Parquet reader decodes it).
        pq.write_table(table, tmp, compression=compression, row_group_size=row_group_size,
                       use_dictionary=others or False, use_byte_stream_split=floats or False)


def write_rows(rows: list[dict[str, Any]], schema: pa.Schema, path: Path, *, schema_version: int,
               params: Mapping[str, Any] | None = None, extra: Mapping[str, Any] | None = None) -> None:
    """A small table (a catalogue, an index, a failure table) from its rows, written as ``write_parquet``
    writes, and not rewritten when the file already holds these rows with this version, these params and
    this ``extra`` metadata: the file stays as it is and a stage with nothing new to do does not build a
    table (pyarrow imports pandas to build one, 0.25 s)."""
    path = Path(path)
    if path.exists():
        def stored(value: Any) -> Any:  # as write_parquet's metadata holds it
            return json.loads(json.dumps(value, sort_keys=True, default=str))

        try:
            meta = read_meta(path)
            same = (meta.get("schema_version") == schema_version
                    and meta.get("params") == stored(_without_execution(dict(params or {})))
                    and all(meta.get(key) == stored(value) for key, value in dict(extra or {}).items())
                    and read_rows(path) == [{name: row.get(name) for name in schema.names} for row in rows])
        except Exception:  # unreadable: rewrite it
            same = False
        if same:
            return
    write_parquet(pa.Table.from_pylist(rows, schema=schema), path, schema_version=schema_version, params=params,
                  extra=extra)


def _leaf_columns(schema: pa.Schema) -> tuple[list[str], list[str]]:
    """The Parquet leaf paths of a table's float and its other columns (lists of floats included)."""
    floats, others = [], []

    def walk(path: str, kind: pa.DataType) -> None:
        if pa.types.is_list(kind) or pa.types.is_large_list(kind) or pa.types.is_fixed_size_list(kind):
            walk(f"{path}.list.element", kind.value_type)
        elif pa.types.is_struct(kind):
            for child in kind:
                walk(f"{path}.{child.name}", child.type)
        else:
            (floats if pa.types.is_float32(kind) or pa.types.is_float64(kind) else others).append(path)

    for field in schema:
        walk(field.name, field.type)
    return floats, others


def write_json(path: Path, payload: Any) -> None:
    """A metrics-style JSON file, written atomically with sorted keys."""
    with atomic_path(Path(path)) as tmp:
        tmp.write_text(json.dumps(payload, indent=2, sort_keys=True) + "\n")


def item_files(folder: Path) -> list[Path]:
    """A stage folder's per-item Parquet files (not ``_failures.parquet`` or other ``_`` files)."""
    folder = Path(folder)
    return sorted(p for p in folder.glob("*.parquet") if not p.name.startswith(("_", "."))) if folder.exists() else []


def read_schema(path: Path) -> pa.Schema:
    """A Parquet file's schema; a missing file, or one that is not Parquet, is an InputError naming
    it (every contract's reader starts here)."""
    from pipeline.core.errors import InputError

    try:
        return pq.read_schema(path)
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except IsADirectoryError:
        raise InputError(path, "a folder, not a Parquet file") from None
    except (pa.ArrowInvalid, OSError) as exc:
        raise InputError(path, f"not a Parquet file ({' '.join(str(exc).split())[:120]})") from None


def read_meta(path: Path) -> dict[str, Any]:
    """The dance3d metadata of a Parquet file ({} if it has none); see ``read_schema`` for bad files."""
    schema = read_schema(path)
    raw = (schema.metadata or {}).get(META_KEY)
    return json.loads(raw) if raw else {}


def read_file_table(path: Path) -> pa.Table:
    """A Parquet file's table, read as one file, not as a dataset: ``pq.read_table`` imports
    pyarrow.dataset and with it pandas, 0.3 s at the start of a stage that may have nothing to do."""
    return pq.ParquetFile(path).read()


def read_rows(path: Path) -> list[dict[str, Any]]:
    """A small Parquet table's rows (:func:`read_file_table`)."""
    return read_file_table(path).to_pylist()


def require_schema(path: Path, version: int, what: str, fix: str) -> dict[str, Any]:
    """The file's dance3d metadata, when it was written at ``version`` of its contract; otherwise
    an InputError naming the file, both versions and ``fix``."""
    from pipeline.core.errors import InputError

    meta = read_meta(path)
    if meta.get("schema_version") != version:
        raise InputError(path, f"{what} schema {meta.get('schema_version')}, this dance3d reads schema {version}: "
                               f"{fix}")
    return meta


def fixed_list(values: np.ndarray, inner: pa.DataType = pa.float32()) -> pa.Array:
    """A (rows x d) numpy array as an Arrow fixed-size list column (the contracts' tensor form)."""
    values = np.asarray(values)
    width = int(np.prod(values.shape[1:])) if values.ndim > 1 else 1
    flat = values.reshape(len(values), width).ravel()
    return pa.FixedSizeListArray.from_arrays(pa.array(flat.astype(inner.to_pandas_dtype()), inner), width)


def column_array(table: pa.Table, name: str, shape: tuple[int, ...] = (), dtype: Any = np.float32) -> np.ndarray:
    """A column as numpy: fixed-size lists become (rows, *shape)."""
    column = table.column(name).combine_chunks()
    if pa.types.is_fixed_size_list(column.type):
        return to_numpy(column.flatten()).astype(dtype, copy=False).reshape(table.num_rows, *shape)
    return to_numpy(column)


def to_numpy(array: pa.Array) -> np.ndarray:
    """An Arrow array as numpy. Numbers and booleans without nulls are read from their buffers:
    pyarrow's own conversion imports pandas (0.25 s at the start of a stage that reads one table)."""
    kind = array.type
    if len(array) == 0 or array.buffers()[1] is None:
        return array.to_numpy(zero_copy_only=False)
    if array.null_count == 0 and (pa.types.is_integer(kind) or pa.types.is_floating(kind)):
        code = "f" if pa.types.is_floating(kind) else "i" if pa.types.is_signed_integer(kind) else "u"
        width = kind.bit_width // 8
        return np.frombuffer(array.buffers()[1], np.dtype(f"<{code}{width}"), len(array), array.offset * width)
    if array.null_count == 0 and pa.types.is_boolean(kind):
        bits = np.unpackbits(np.frombuffer(array.buffers()[1], np.uint8), bitorder="little")
        return bits[array.offset:array.offset + len(array)].astype(bool)
    return array.to_numpy(zero_copy_only=False)
