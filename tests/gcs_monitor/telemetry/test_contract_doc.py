"""docs/telemetry.md carries exactly the contract table that telemetry/contract.py renders."""

from __future__ import annotations

from pathlib import Path

from gcs_monitor.telemetry.contract import ROWS, TABLE_HEADER, contract_markdown

DOC = Path(__file__).resolve().parents[3] / "docs" / "telemetry.md"


def extract_markdown_table(text: str, header: str = TABLE_HEADER) -> str:
    """The contract table inside a Markdown document: the header line and following rows."""
    lines = text.splitlines()
    first = header.splitlines()[0]
    try:
        i = lines.index(first)
    except ValueError:
        return ""
    j = i
    while j < len(lines) and lines[j].startswith("|"):
        j += 1
    return "\n".join(lines[i:j])


def test_every_contract_row_appears_in_the_doc():
    doc = DOC.read_text(encoding="utf-8")
    table = extract_markdown_table(doc)
    rendered = contract_markdown().splitlines()
    assert len(rendered) == len(ROWS) + 2  # header + separator + one line per row
    doc_lines = table.splitlines()
    missing = [line for line in rendered if line not in doc_lines]
    assert not missing, ("docs/telemetry.md is out of date; regenerate its table from "
                         f"contract_markdown(). Missing rows: {missing}")
    assert table == contract_markdown()  # and nothing extra


def test_every_scaled_row_names_its_conversion():
    for r in ROWS:
        if r.scale is not None and r.scale != 1:
            assert "→" in r.conversion, r  # a non-unit scale says from which unit to which
