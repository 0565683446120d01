"""Ground truth beside every run (never on the monitored link).

``<run>.truth.npz`` holds

* ``state.<field>``: every :class:`~sim_vehicle.state.TrueState` field per truth step
  (``state.t_s`` is the time axis; vectors are (N, 3));
* ``fault.<channel>.t_s`` / ``fault.<channel>.value``: the fault value actually applied to that
  channel at each of its samples (measured minus healthy measurement, SI);
* ``fault_events_json``: JSON list of fault events (sensor and actuator, start/end, parameters);
* ``scenario_toml``: the scenario as run.

Everything is written to a temporary file in the same directory and renamed, so a reader never
sees a half-written file.
"""

from __future__ import annotations

import json
import os
from dataclasses import fields
from pathlib import Path

import numpy as np

from sim_vehicle.actuators.faults import ACTUATORS
from sim_vehicle.scenario import Scenario, to_toml
from sim_vehicle.state import TrueState

STATE_FIELDS = tuple(f.name for f in fields(TrueState))


def fault_events(sc: Scenario) -> list[dict[str, object]]:
    """The scenario's faults as plain dicts (sensor and actuator), sorted by start time."""
    ev: list[dict[str, object]] = []
    for f in sc.faults:
        ev.append({"type": "sensor", "channel": f.channel, "kind": f.kind,
                   "t_start_s": f.t_start_s, "t_end_s": f.t_end_s, "params": dict(f.params)})
    for a in sc.actuator_faults:
        ev.append({"type": "actuator", "channel": f"actuator.{ACTUATORS[a.surface]}",
                   "kind": a.kind, "t_start_s": a.t_start_s, "t_end_s": a.t_end_s,
                   "params": {"amplitude": a.amplitude, "frequency_hz": a.frequency_hz,
                              "phase_rad": a.phase_rad}})
    ev.sort(key=lambda e: float(e["t_start_s"]))  # type: ignore[arg-type]
    return ev


class TruthRecorder:
    """Collects the true state at the truth rate; :meth:`save` writes the NPZ atomically."""

    def __init__(self) -> None:
        self._rows: dict[str, list[object]] = {k: [] for k in STATE_FIELDS}

    def record(self, st: TrueState) -> None:
        for k in STATE_FIELDS:
            self._rows[k].append(getattr(st, k))

    def __len__(self) -> int:
        return len(self._rows["t_s"])

    def arrays(self) -> dict[str, np.ndarray]:
        return {f"state.{k}": np.asarray(v, dtype=float) for k, v in self._rows.items()}

    def save(self, path: Path, sc: Scenario,
             fault_log: dict[str, tuple[list[float], list[float]]]) -> Path:
        data = self.arrays()
        for ch, (ts, vals) in fault_log.items():
            data[f"fault.{ch}.t_s"] = np.asarray(ts, dtype=float)
            data[f"fault.{ch}.value"] = np.asarray(vals, dtype=float)
        data["fault_events_json"] = np.array(json.dumps(fault_events(sc)))
        data["scenario_toml"] = np.array(to_toml(sc))
        return atomic_savez(Path(path), data)


def atomic_savez(path: Path, data: dict[str, np.ndarray]) -> Path:
    tmp = path.with_name(path.name + ".part")
    with open(tmp, "wb") as fh:
        np.savez_compressed(fh, **data)  # type: ignore[arg-type]
    os.replace(tmp, path)
    return path


def atomic_write_text(path: Path, text: str) -> Path:
    tmp = path.with_name(path.name + ".part")
    tmp.write_text(text)
    os.replace(tmp, path)
    return path


def load_truth(path: Path) -> dict[str, object]:
    """Read a truth NPZ back: arrays by key, ``fault_events`` decoded from JSON."""
    with np.load(path, allow_pickle=False) as z:
        out: dict[str, object] = {k: z[k] for k in z.files}
    out["fault_events"] = json.loads(str(out.pop("fault_events_json")))
    out["scenario_toml"] = str(out["scenario_toml"])
    return out
