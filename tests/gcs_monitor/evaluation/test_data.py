"""Where the real flight data is (gcs_monitor.evaluation.data.real_data_dir)."""

from __future__ import annotations

from pathlib import Path

import pytest

from gcs_monitor.evaluation import data


def test_explicit_path_wins_then_the_variable_then_the_default(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(data.DATA_DIR_ENV, raising=False)
    assert data.real_data_dir() == data.DEFAULT_DATA_DIR
    monkeypatch.setenv(data.DATA_DIR_ENV, "")  # set but empty: as if unset
    assert data.real_data_dir() == data.DEFAULT_DATA_DIR
    monkeypatch.setenv(data.DATA_DIR_ENV, str(tmp_path / "env"))
    assert data.real_data_dir() == tmp_path / "env"
    assert data.real_data_dir(tmp_path / "cli") == tmp_path / "cli"
    assert data.real_data_dir(str(tmp_path / "cli")) == tmp_path / "cli"


def test_default_is_beside_the_repository_not_an_absolute_machine_path() -> None:
    repo = Path(__file__).resolve().parents[3]  # tests/gcs_monitor/evaluation/ -> repository
    assert data.REPO_ROOT == repo
    assert (data.REPO_ROOT / "pyproject.toml").is_file()
    assert data.DEFAULT_DATA_DIR == repo.parent / "shared" / "data" / "real"


def test_missing_file_names_the_variable_and_the_place(tmp_path: Path) -> None:
    (tmp_path / "here.csv").write_text("x\n")
    assert data.real_data_file(tmp_path, "here.csv") == tmp_path / "here.csv"
    with pytest.raises(data.RealDataMissing) as exc:
        data.real_data_file(tmp_path, "zipline_launch")
    msg = str(exc.value)
    assert data.DATA_DIR_ENV in msg and str(tmp_path / "zipline_launch") in msg
    assert isinstance(exc.value, FileNotFoundError)
