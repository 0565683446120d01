"""docs/configuration.md is generated from the declarations (`gcs-monitor config --markdown`)
and every key of the default configuration is documented."""

from __future__ import annotations

from pathlib import Path

from gcs_monitor.cli import main
from gcs_monitor.config import config_markdown
from gcs_monitor.config.loader import config_tables

DOC = Path(__file__).resolve().parents[3] / "docs" / "configuration.md"


def test_configuration_page_is_current() -> None:
    assert DOC.read_text(encoding="utf-8") == config_markdown(), (
        "docs/configuration.md is stale: run `gcs-monitor config --markdown > "
        "docs/configuration.md`")


def test_every_key_has_a_doc() -> None:
    undocumented = [f"{t.name}.{e.key}" for t in config_tables() for e in t.entries if not e.doc]
    assert undocumented == []


def test_cli_prints_the_defaults(capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(["config", "--defaults"]) == 0
    out = capsys.readouterr().out
    assert "[airdata.fdi.aoa]\nthreshold_deg = 1.0" in out
    assert main(["config"]) == 2
