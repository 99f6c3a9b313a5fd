"""Human-edited CSV files: read with line numbers, validate headers, write safely."""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Sequence

from pipeline.core.errors import InputError
from pipeline.core.storage import atomic_path


@dataclass(frozen=True)
class CsvRow:
    """One data row and the 1-based line it starts on in its file."""

    line: int
    values: dict[str, str]

    def get(self, column: str) -> str:
        return (self.values.get(column) or "").strip()


def read_csv(path: Path, required: Sequence[str], optional: Sequence[str] = ()) -> list[CsvRow]:
    """Read a CSV whose header must contain ``required`` and may contain ``optional``.

    Blank lines and lines starting with ``#`` are skipped, so annotators can leave comments.
    Every problem raises InputError naming the file and line.
    """
    path = Path(path)
    if not path.exists():
        raise InputError(path, "file not found")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(path, f"not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    lines = text.splitlines(keepends=True)
    # Drop comment lines but remember original line numbers.
    kept = [(i + 1, ln) for i, ln in enumerate(lines) if ln.strip() and not ln.lstrip().startswith("#")]
    if not kept:
        raise InputError(path, "empty file: expected a header line with " + ", ".join(required))
    header_line, header_text = kept[0]
    header = [h.strip() for h in next(csv.reader([header_text]))]
    missing = [c for c in required if c not in header]
    if missing:
        raise InputError(path, f"missing column(s) {', '.join(missing)} in header {header}", header_line)
    known = set(required) | set(optional)
    extra = [c for c in header if c not in known]
    if extra:
        raise InputError(
            path,
            f"unknown column(s) {', '.join(extra)}; allowed: {', '.join(list(required) + list(optional))}",
            header_line,
        )
    dupes = {c for c in header if header.count(c) > 1}
    if dupes:
        raise InputError(path, f"duplicate column(s) {', '.join(sorted(dupes))}", header_line)
    rows = []
    for line_no, line_text in kept[1:]:
        cells = next(csv.reader([line_text]))
        if len(cells) != len(header):
            raise InputError(path, f"expected {len(header)} fields, found {len(cells)}", line_no)
        rows.append(CsvRow(line_no, dict(zip(header, cells))))
    return rows


_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def neutralise_cell(value: str) -> str:
    """Stop spreadsheet formula injection in free-text cells written back to annotators.

    Numbers (including negative ones) are left alone; other text starting with a
    formula character gets a leading apostrophe.
    """
    if value and value.startswith(_FORMULA_START):
        try:
            float(value)
            return value
        except ValueError:
            return "'" + value
    return value


def write_csv(path: Path, header: Sequence[str], rows: Iterable[Sequence[object]],
              comments: Sequence[str] = ()) -> None:
    """Write a CSV atomically with ``\\n`` line ends and neutralised text cells."""
    buf = io.StringIO()
    for comment in comments:  # leading "# " lines, which read_csv skips
        buf.write(f"# {comment}\n")
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    for row in rows:
        writer.writerow([neutralise_cell(str(v)) if isinstance(v, str) else v for v in row])
    with atomic_path(Path(path)) as tmp:
        tmp.write_text(buf.getvalue(), encoding="utf-8")
