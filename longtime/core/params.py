"""Declared parameters of problems and schemes, and their validation.

A problem or a scheme lists its parameters as ``Param`` objects; ``resolve`` merges user
settings over the defaults and checks every value, so that a bad value is reported with
the argument's name and what is allowed. Each parameter declares its role and whether it
sweeps; longtime.core.roles derives from these declarations what every command does with it.
"""
from __future__ import annotations

import difflib
import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np


class InputError(ValueError):
    """Bad user input: unknown names, invalid values, incompatible pairs."""


# what a parameter is, in the order a cell's sweep axes nest (outermost first):
#   step      the time step of a fixed-step scheme (dt)
#   accuracy  what sets an adaptive scheme's accuracy (tol, eps_res, a plugin's rtol): the
#             parameter `longtime match` searches, switched off by the stability measurement
#   order     a series order N
#   horizon   a final time
#   physical  a problem's parameter (kepler's e, toda's d)
#   option    any other setting of a scheme (max_iter, a controller, a variant)
ROLES = ("step", "accuracy", "order", "horizon", "physical", "option")
# roles that sweep unless a parameter says otherwise: the default matrix varies them
SWEEPING_ROLES = ("step", "accuracy", "order", "horizon")
# the range of an integer parameter (numba compiles integers as int64)
INT64_MIN, INT64_MAX = -2**63, 2**63 - 1


@dataclass(frozen=True)
class Param:
    default: Any
    doc: str
    kind: type = float
    positive: bool = False  # strictly > 0
    minimum: float | None = None  # inclusive
    maximum: float | None = None  # inclusive
    choices: tuple | None = None
    role: str = "option"  # one of ROLES
    sweeps: bool | None = None  # None: as its role (SWEEPING_ROLES sweep)
    # the range `longtime match` searches an accuracy parameter over (None: 1e-14 to 0.1)
    search: tuple[float, float] | None = None
    # why a value below ``minimum`` is refused, where that is not plain from the number
    minimum_reason: str | None = None

    def __post_init__(self):
        if self.role not in ROLES:
            raise ValueError(f"Param role {self.role!r} is not one of {', '.join(ROLES)}")
        if self.sweeps is None:
            object.__setattr__(self, "sweeps", self.role in SWEEPING_ROLES)

    def _typed(self, value: Any) -> bool:
        if self.kind in (int, float):
            return _is_real(value)
        if self.kind is bool:
            return isinstance(value, (bool, np.bool_))
        return not (isinstance(value, bool) or value is None)

    def allowed(self) -> str:
        if self.choices is not None:
            return "one of " + ", ".join(map(str, self.choices))
        parts = [self.kind.__name__]
        if self.positive:
            parts.append("> 0")
        if self.minimum is not None:
            parts.append(f">= {self.minimum}")
        if self.maximum is not None:
            parts.append(f"<= {self.maximum}")
        return " ".join(parts)

    def parse(self, name: str, value: Any, strict: bool = False) -> Any:
        """Convert (from a string too) and check one value; raise InputError naming `name`.
        ``strict`` (a Python value from the API, not command-line text): a number must be a
        number (not a string, not a bool), a bool a bool."""
        if strict and not self._typed(value):
            raise InputError(f"{name}={value!r} is not valid: expected {self.allowed()}")
        try:
            if self.kind is bool and isinstance(value, str):
                if value.lower() not in ("true", "false", "1", "0", "yes", "no"):
                    raise ValueError(value)
                v = value.lower() in ("true", "1", "yes")
            elif self.kind is int and not isinstance(value, (int, np.integer)):
                try:
                    v = int(value) if isinstance(value, str) else None  # exact, however many digits
                except ValueError:
                    v = None
                if v is None:
                    number = float(value)  # "3.0", 3.0 and "1e3" are integers; 2.5 and "2.5" are errors
                    if not number.is_integer():
                        raise ValueError(value)
                    v = int(number)
            else:
                v = self.kind(value)
        except (TypeError, ValueError):
            raise InputError(f"{name}={value!r} is not valid: expected {self.allowed()}") from None
        if self.choices is not None and v not in self.choices:
            raise InputError(f"{name}={value!r} is not valid: expected {self.allowed()}")
        if self.kind is int and isinstance(v, (int, np.integer)) and not isinstance(v, bool):
            if not INT64_MIN <= v <= INT64_MAX:
                raise InputError(f"{name}={value!r} is not valid: outside the 64-bit integers ({self.allowed()})")
            v = int(v)
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            if isinstance(v, float) and not math.isfinite(v):
                raise InputError(f"{name}={value!r} is not valid: must be finite ({self.allowed()})")
            if self.minimum_reason and self.minimum is not None and 0 < v < self.minimum:
                raise InputError(f"{name}={value!r} is not valid: {self.minimum_reason} ({self.allowed()})")
            bad = (
                (self.positive and not v > 0)
                or (self.minimum is not None and v < self.minimum)
                or (self.maximum is not None and v > self.maximum)
            )
            if bad:
                raise InputError(f"{name}={value!r} is not valid: expected {self.allowed()}")
        return v


def resolve(declared: Mapping[str, Param], given: Mapping[str, Any], owner: str) -> dict[str, Any]:
    """Defaults overridden by `given`; every given key must be declared."""
    unknown = sorted(set(given) - set(declared))
    if unknown:
        valid = ", ".join(sorted(declared)) or "none"
        raise InputError(f"unknown parameter {', '.join(unknown)} for {owner}; valid parameters: {valid}")
    out = {}
    for key, spec in declared.items():
        out[key] = spec.parse(f"{owner}: {key}", given[key]) if key in given else spec.default
    return out


def check_choice(argument: str, value: str, allowed) -> str:
    check_choices(argument, [value], allowed)
    return value


def check_choices(argument: str, values, allowed) -> None:
    """Every value must be allowed: one InputError naming each unknown value, with the
    closest allowed names ("did you mean") and the full list."""
    allowed = sorted(allowed)
    unknown = [v for v in dict.fromkeys(values) if v not in allowed]
    if not unknown:
        return
    parts = []
    for v in unknown:
        close = difflib.get_close_matches(str(v), allowed, n=3, cutoff=0.6)
        parts.append(f"'{v}'" + (f" (did you mean {' or '.join(close)}?)" if close else ""))
    plural = "s" if len(unknown) > 1 else ""
    raise InputError(f"unknown {argument}{plural} {', '.join(parts)}; valid {argument}s: {', '.join(allowed)}")


# the longest time limit (seconds) taken: about 31 years, where a clock's deadline and the
# waits on it still count (1e308 s overflows them)
MAX_SECONDS = 1e9


def check_time_span(t0: float, t_final: float, owner: str = "") -> None:
    if t_final is None:
        raise InputError(f"t_final=None is not valid: {owner or 'the problem'} has no default_t_final; "
                         f"give t_final (a finite number > t0={t0})")
    if not _is_real(t_final) or not math.isfinite(t_final) or not t_final > t0:
        raise InputError(f"t_final={t_final!r} is not valid: must be finite and > t0={t0}")


def check_state(name: str, u) -> None:
    u = np.asarray(u, dtype=float)
    if u.ndim != 1 or u.size == 0:
        raise InputError(f"{name} must be a non-empty 1-D array, got shape {u.shape}")
    if not np.all(np.isfinite(u)):
        bad = np.flatnonzero(~np.isfinite(u))
        raise InputError(f"{name} is not finite at components {bad.tolist()}")


# ------------------------------------------------------------------ arguments of the API
# One rule and one wording for every front end: "NAME=VALUE is not valid: expected WHAT".
def _is_real(value: Any) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def check_number(name: str, value: Any, *, positive: bool = False, minimum: float | None = None,
                 maximum: float | None = None, integer: bool = False, none: bool = False) -> Any:
    """``value`` as a finite real number (an integer with ``integer``), > 0 with ``positive``,
    >= ``minimum``, <= ``maximum``; None passes with ``none``. A bool or a string is not a
    number here: the API takes Python values, the command line converts its text before it
    gets here (the error names a value of another type by its type)."""
    if value is None and none:
        return None
    allowed = "an integer" if integer else "a finite number"
    allowed += " > 0" if positive else (f" >= {minimum:g}" if minimum is not None else "")
    allowed += f" and <= {maximum:g}" if maximum is not None else ""
    allowed += " or None" if none else ""
    ok = _is_real(value) and math.isfinite(float(value))
    if ok and integer:
        ok = float(value).is_integer() and not isinstance(value, (float, np.floating))
    if ok:
        ok = not ((positive and not value > 0) or (minimum is not None and value < minimum)
                  or (maximum is not None and value > maximum))
    if not ok:
        got = "" if _is_real(value) or value is None else f" (got a {type(value).__name__})"
        raise InputError(f"{name}={value!r} is not valid: expected {allowed}{got}")
    return int(value) if integer else value


def check_values(name: str, value: Any) -> list:
    """The values of a keyword that takes a value or a list of them: a list must not be
    empty (an empty sweep would quietly run the default, or nothing)."""
    if isinstance(value, (list, tuple, np.ndarray, range, set, frozenset)):
        values = list(value)
        if not values:
            raise InputError(f"{name}={value!r} is not valid: expected a value or a non-empty list of values")
        return values
    return [value]


def unknown_parameter(argument: str, key: str, valid, owners: str) -> InputError:
    """The error for a parameter no selected problem or scheme declares: the argument as the
    front end spells it (``--set dtt``, ``keyword dtt``), the closest names and the full list."""
    valid = sorted(valid)
    close = difflib.get_close_matches(key, valid, n=3, cutoff=0.6)
    hint = f" (did you mean {' or '.join(close)}?)" if close else ""
    return InputError(f"{argument}: unknown parameter{hint} for {owners}; their parameters: "
                      f"{', '.join(valid) or 'none'}")
