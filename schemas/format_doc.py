"""Generate the column tables of ``schemas/FORMAT.md`` from the record types' ``COLUMNS``.

``python -m mimicbench.schemas.format_doc`` rewrites the part of FORMAT.md between the markers; a test
checks that the file is up to date, so the documentation cannot drift from the code.
"""
from __future__ import annotations

from pathlib import Path

from mimicbench.schemas.tables import RECORD_TYPES

BEGIN = "<!-- BEGIN GENERATED COLUMNS (python -m mimicbench.schemas.format_doc) -->"
END = "<!-- END GENERATED COLUMNS -->"
FORMAT_MD = Path(__file__).with_name("FORMAT.md")


def arrow_type_text(col) -> str:
    return str(col.arrow_type()).replace("<item: ", "<").replace("fixed_size_list<element: ", "fixed_size_list<")


def column_tables() -> str:
    """Markdown: one table per record type listing name, Arrow type, nullability and meaning."""
    out = []
    for table, rtype in RECORD_TYPES.items():
        out.append(f"### `{table}` ({rtype.__name__})\n")
        out.append((rtype.__doc__ or "").strip().split("\n\n")[0].replace("\n", " ").replace("    ", " ") + "\n")
        out.append("| column | Arrow type | null | meaning |")
        out.append("|---|---|---|---|")
        for c in rtype.COLUMNS:
            out.append(f"| `{c.name}` | `{arrow_type_text(c)}` | {'yes' if c.nullable else 'no'} | {c.doc} |")
        out.append("")
    return "\n".join(out)


def render(text: str) -> str:
    """FORMAT.md text with the generated part replaced."""
    if BEGIN not in text or END not in text:
        raise ValueError(f"FORMAT.md: expected the markers {BEGIN!r} and {END!r}")
    head, rest = text.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    return head + BEGIN + "\n\n" + column_tables() + "\n" + END + tail


if __name__ == "__main__":
    FORMAT_MD.write_text(render(FORMAT_MD.read_text()))
    print(f"updated {FORMAT_MD}")
