"""Sensor fault profiles: pure functions of time (and of the true value where needed).

A fault on a channel either *adds* a value ``f(t)`` to the healthy measurement
(``y = x + n + f``) or *replaces* it (jamming: ``y = x(t0)``). Either way the fault value that the
truth file records is ``y - (x + n)``, i.e. exactly what the fault did to the measurement.

Kinds and their SI parameters (the key carries the channel's SI unit, written ``<U>`` here):

========== ============================================ =========================================
kind       parameters                                    f(t), tau = t - t_start
========== ============================================ =========================================
bias       bias_<U>                                      b
drift      rate_<U>_per_s, [max_<U>]                     clip(r tau, -max, max)
oscillation amplitude_<U>, frequency_hz, [phase_rad]     A sin(2 pi f tau + phase)
runaway    rate_<U>_per_s, limit_<U>                     clip(r tau, -limit, limit)
jam        -                                             replaces y with x(t_start) (stuck)
nrz        [level] (default 0.1) or gain                 (level - 1) x(t): the output falls to
                                                         level x(t); or gain x(t) (Wan2018 T. II)
noise      sigma_<U>                                     sigma N(0, 1)
scale      factor                                        (factor - 1) x(t)
expr       expr_<U> (string of t, tau)                   eval(expr), e.g. 4*sin(0.5*pi*t)
========== ============================================ =========================================

Paper notes
-----------
* Wan2018 Table II gives "Non-return to zero: 10% x current value" without further definition.
  We read it as the value the output takes: it falls towards zero but not to it,
  ``y = 0.1 x(t)`` (``level``), so ``f = -0.9 x(t)``. The name, Fig. 6(b) (three CAS probes
  with this fault drive the nominal controller into fast AoA transients) and the paper's own
  MDR 0 % at J_th = 2.9 deg support it (docs/papers-notes.md). The literal additive reading
  ``f = 0.1 x(t)`` stays available as ``gain`` = 0.1.
* Chen2020's "fast runaway" of the yaw-rate sensor is a ramp at 0.4 deg/s^2 capped at 5 deg/s;
  ``runaway`` and ``drift`` with ``max`` therefore share one formula; runaway requires the limit.
"""

from __future__ import annotations

import ast
import math
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

FAULT_KINDS = ("bias", "drift", "oscillation", "runaway", "jam", "nrz", "noise", "scale", "expr")
REPLACING_KINDS = frozenset({"jam"})
NRZ_LEVEL_DEFAULT = 0.1  # Wan2018 Table II: the output falls to 10% x current value

KIND_PARAMS: dict[str, dict[str, tuple[bool, str]]] = {
    # param stem: (required, unit kind: "u" channel unit, "u/s" channel unit per s, or fixed key)
    "bias": {"bias": (True, "u")},
    "drift": {"rate": (True, "u/s"), "max": (False, "u")},
    "oscillation": {
        "amplitude": (True, "u"),
        "frequency_hz": (True, "fixed"),
        "phase": (False, "angle"),
    },
    "runaway": {"rate": (True, "u/s"), "limit": (True, "u")},
    "jam": {},
    "nrz": {"level": (False, "fixed"), "gain": (False, "fixed")},
    "noise": {"sigma": (True, "u")},
    "scale": {"factor": (True, "fixed")},
    "expr": {"expr": (True, "u")},
}


@dataclass(frozen=True, slots=True)
class FaultSpec:
    """One sensor fault on one channel, parameters already in SI.

    Parameters
    ----------
    channel : channel name, e.g. ``"imu0.acc.x"``, ``"aoa1"`` (see sensors/channels.py)
    kind : one of ``FAULT_KINDS``
    t_start_s, t_end_s : active for ``t_start_s <= t < t_end_s`` (``None`` = to the end)
    params : ((key, value), ...) with SI unit suffixes, e.g. ``(("bias_rad", 0.035),)``;
        an ``expr_<U>`` value is the expression string in the config unit, with the factor to
        SI in ``si_factor``
    """

    channel: str
    kind: str
    t_start_s: float
    t_end_s: float | None
    params: tuple[tuple[str, object], ...] = ()

    def p(self) -> dict[str, object]:
        return dict(self.params)

    def get(self, stem: str, default: float | None = None) -> float:
        """The value of the parameter whose key starts with ``stem`` (unit suffix ignored)."""
        for k, v in self.params:
            if k == stem or k.startswith(stem + "_"):
                return float(v)  # type: ignore[arg-type]
        if default is None:
            raise KeyError(f"{self.kind} fault on {self.channel}: missing parameter {stem}_*")
        return default

    def active(self, t_s: float) -> bool:
        return t_s >= self.t_start_s and (self.t_end_s is None or t_s < self.t_end_s)


# ---------------------------------------------------------------------------------------------
# pure profiles
# ---------------------------------------------------------------------------------------------


def bias_profile(tau_s: float, bias: float) -> float:
    """Constant offset."""
    return bias


def drift_profile(tau_s: float, rate_per_s: float, cap: float = math.inf) -> float:
    """Linear drift ``r tau``, magnitude capped (Chen2020 sec. V: capped at 5 deg/s)."""
    return min(max(rate_per_s * tau_s, -cap), cap)


def oscillation_profile(
    tau_s: float, amplitude: float, frequency_hz: float, phase_rad: float = 0.0
) -> float:
    """Sinusoid ``A sin(2 pi f tau + phase)`` (Wan2018 Table II oscillation)."""
    return amplitude * math.sin(2.0 * math.pi * frequency_hz * tau_s + phase_rad)


def runaway_profile(tau_s: float, rate_per_s: float, limit: float) -> float:
    """Rate-limited ramp to a limit (Wan2018 Table II runaway rates; Chen2020 5 deg/s cap)."""
    return drift_profile(tau_s, rate_per_s, abs(limit))


def nrz_profile(x_true: float, level: float = NRZ_LEVEL_DEFAULT,
                gain: float | None = None) -> float:
    """Non-return to zero (Wan2018 Table II, "10% x current value"): the output falls to
    ``level x(t)``, so ``f = (level - 1) x(t)``; with ``gain`` the literal additive reading
    ``f = gain x(t)`` instead."""
    if gain is not None:
        return gain * x_true
    return (level - 1.0) * x_true


def scale_profile(x_true: float, factor: float) -> float:
    """Scale-factor error: ``y = factor x`` so ``f = (factor - 1) x``."""
    return (factor - 1.0) * x_true


# ---------------------------------------------------------------------------------------------
# expression faults (to reproduce paper tables verbatim)
# ---------------------------------------------------------------------------------------------

_EXPR_FUNCS: dict[str, object] = {
    "sin": math.sin,
    "cos": math.cos,
    "tan": math.tan,
    "exp": math.exp,
    "sqrt": math.sqrt,
    "abs": abs,
    "min": min,
    "max": max,
    "pi": math.pi,
}
_EXPR_NAMES = frozenset(_EXPR_FUNCS) | {"t", "tau"}
_EXPR_NODES = (
    ast.Expression,
    ast.BinOp,
    ast.UnaryOp,
    ast.Call,
    ast.Name,
    ast.Load,
    ast.Constant,
    ast.Add,
    ast.Sub,
    ast.Mult,
    ast.Div,
    ast.Pow,
    ast.USub,
    ast.UAdd,
)


class ExpressionError(ValueError):
    pass


def compile_expression(text: str) -> Callable[[float, float], float]:
    """Compile a fault expression of ``t`` (absolute time, s) and ``tau`` (since fault start, s).

    Only arithmetic, numbers and sin/cos/tan/exp/sqrt/abs/min/max/pi are allowed, e.g. Lu2016
    Table 2 ``"4*sin(0.5*pi*t)"`` or ``"0.1*(t-10)"``.
    """
    try:
        tree = ast.parse(text, mode="eval")
    except SyntaxError as e:
        raise ExpressionError(f"cannot parse expression {text!r}: {e.msg}") from None
    for node in ast.walk(tree):
        if not isinstance(node, _EXPR_NODES):
            raise ExpressionError(f"expression {text!r}: {type(node).__name__} not allowed")
        if isinstance(node, ast.Name) and node.id not in _EXPR_NAMES:
            raise ExpressionError(
                f"expression {text!r}: unknown name {node.id!r}; allowed: {sorted(_EXPR_NAMES)}"
            )
        if isinstance(node, ast.Constant) and not isinstance(node.value, int | float):
            raise ExpressionError(f"expression {text!r}: only numbers are allowed as constants")
    code = compile(tree, "<fault expression>", "eval")
    env = {"__builtins__": {}, **_EXPR_FUNCS}

    def f(t: float, tau: float) -> float:
        return float(eval(code, env, {"t": t, "tau": tau}))  # noqa: S307 - AST whitelisted above

    return f


# ---------------------------------------------------------------------------------------------
# the injector: applies the specs of one run, keeps the little state jamming/noise need
# ---------------------------------------------------------------------------------------------


def fault_seed(seed: int, index: int, channel: str) -> np.random.SeedSequence:
    """Stable per-fault seed (independent of Python's hash randomisation)."""
    return np.random.SeedSequence([seed, 0xFA17, index, zlib.crc32(channel.encode())])


@dataclass
class _ActiveFault:
    spec: FaultSpec
    rng: np.random.Generator
    expr: Callable[[float, float], float] | None = None
    jam_value: float | None = None


@dataclass
class FaultInjector:
    """Applies a run's sensor faults channel by channel.

    Parameters
    ----------
    specs : all sensor faults of the run
    seed : scenario seed (noise faults draw from their own seeded generators)
    """

    specs: tuple[FaultSpec, ...]
    seed: int = 0
    _by_channel: dict[str, list[_ActiveFault]] = field(default_factory=dict, init=False)

    def __post_init__(self) -> None:
        for i, s in enumerate(self.specs):
            af = _ActiveFault(s, np.random.default_rng(fault_seed(self.seed, i, s.channel)))
            if s.kind == "expr":
                af.expr = compile_expression(str(s.p()[_key(s, "expr")]))
            self._by_channel.setdefault(s.channel, []).append(af)

    @property
    def channels(self) -> list[str]:
        return list(self._by_channel)

    def apply(self, channel: str, t_s: float, x_true: float, healthy: float) -> float:
        """Measured value of ``channel`` at ``t_s`` given the true and the healthy (noisy) value."""
        y = healthy
        for af in self._by_channel.get(channel, ()):
            s = af.spec
            if not s.active(t_s):
                continue
            tau = t_s - s.t_start_s
            k = s.kind
            if k == "jam":
                if af.jam_value is None:
                    af.jam_value = x_true  # stuck at the value at fault start
                y = af.jam_value
                continue
            y += additive_value(s, t_s, tau, x_true, af.rng, af.expr)
        return y


def _key(spec: FaultSpec, stem: str) -> str:
    for k, _ in spec.params:
        if k == stem or k.startswith(stem + "_"):
            return k
    raise KeyError(stem)


def additive_value(
    s: FaultSpec,
    t_s: float,
    tau_s: float,
    x_true: float,
    rng: np.random.Generator,
    expr: Callable[[float, float], float] | None = None,
) -> float:
    """The additive fault value of a non-replacing fault (the table in the module docstring)."""
    k = s.kind
    if k == "bias":
        return bias_profile(tau_s, s.get("bias"))
    if k == "drift":
        return drift_profile(tau_s, s.get("rate"), s.get("max", math.inf))
    if k == "oscillation":
        return oscillation_profile(tau_s, s.get("amplitude"), s.get("frequency_hz"),
                                   s.get("phase", 0.0))
    if k == "runaway":
        return runaway_profile(tau_s, s.get("rate"), s.get("limit"))
    if k == "nrz":
        gain = s.get("gain", math.nan)  # NaN: not given
        return nrz_profile(x_true, s.get("level", NRZ_LEVEL_DEFAULT),
                           None if math.isnan(gain) else gain)
    if k == "scale":
        return scale_profile(x_true, s.get("factor"))
    if k == "noise":
        return s.get("sigma") * float(rng.standard_normal())
    if k == "expr":
        assert expr is not None
        factor = float(s.p().get("si_factor", 1.0))  # type: ignore[arg-type]
        return factor * expr(t_s, tau_s)
    raise ValueError(f"unknown fault kind {k!r}")
