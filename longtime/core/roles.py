"""What each declared parameter is for, answered from the declarations (``Param.role`` and
``Param.sweeps``) of a set of problem and scheme classes: which parameters sweep, which set
a scheme's accuracy, which a kernel reads at run time. The built-in schemes and problems
declare their roles as a plugin does; no command names a parameter to decide this.
"""
from __future__ import annotations

from typing import Iterable

from longtime.core.params import ROLES, Param

# The parameters with a field of their own in every row (null where a scheme has none) and
# a flag of their own on the command line (--dt, --order, --tol, --eps-res): the JSON
# contract (README.md), in its order, with each one's role and the flag's help. A plugin's
# other parameters, swept or not, are in the row's ``settings`` and ``parameters``.
ROW_PARAMETERS: dict[str, tuple[str, str]] = {
    "dt": ("step", "time steps (fixed-step schemes)"),
    "order": ("order", "series orders N (taylor, bpl)"),
    "tol": ("accuracy", "tolerances (adaptive schemes)"),
    "eps_res": ("accuracy", "BPL residual bounds"),
}
# roles a scheme's accuracy is set by, in the order `longtime match` prefers them
ACCURACY_ROLES = ("accuracy", "step")
# roles whose values a compiled kernel reads at run time: cells that differ only in these
# share a kernel
RUN_TIME_ROLES = ("step", "accuracy")
# the range `longtime match` searches an accuracy parameter over, unless it declares one
DEFAULT_SEARCH = (1e-14, 1e-1)


def flag(name: str) -> str:
    """The command-line option of a parameter: --dt, --eps-res; --set NAME for the rest."""
    return f"--{name.replace('_', '-')}" if name in ROW_PARAMETERS else f"--set {name}"


def declared(classes: Iterable[type]) -> dict[str, Param]:
    """Every parameter the classes declare (the first declaration of a name)."""
    out: dict[str, Param] = {}
    for cls in classes:
        for name, param in cls.parameters.items():
            out.setdefault(name, param)
    return out


def rank(param: Param) -> int:
    return ROLES.index(param.role)


def with_role(classes: Iterable[type], *roles: str) -> list[str]:
    """The names of the parameters of ``roles``, by role (in ``roles``' order), then as declared."""
    params = declared(classes)
    return [n for role in roles for n, p in params.items() if p.role == role]


def swept(classes: Iterable[type]) -> list[str]:
    """The parameters that sweep, in the order a cell's axes nest (by role, then as declared)."""
    params = declared(classes)
    return sorted((n for n, p in params.items() if p.sweeps), key=lambda n: rank(params[n]))


def accuracy(cls: type) -> list[str]:
    """The parameters that set a scheme's accuracy: accuracy ones first, then its step."""
    return with_role([cls], *ACCURACY_ROLES)


def run_time(classes: Iterable[type]) -> list[str]:
    """The parameters a compiled kernel reads at run time (not closed over)."""
    return with_role(classes, *RUN_TIME_ROLES)


def search_range(param: Param) -> tuple[float, float]:
    """The range `longtime match` searches an accuracy parameter over."""
    return param.search or DEFAULT_SEARCH


def row_columns() -> list[str]:
    """The row parameters in the order a cell's axes nest (by role): dt, tol, eps_res, order."""
    return sorted(ROW_PARAMETERS, key=lambda k: ROLES.index(ROW_PARAMETERS[k][0]))


def row_fields(role: str) -> list[str]:
    """The row parameters of ``role``: row_fields("accuracy") == ["tol", "eps_res"]."""
    return [k for k, (r, _) in ROW_PARAMETERS.items() if r == role]


def order_axes(names: Iterable[str], classes: Iterable[type]) -> list[str]:
    """``names`` in the order a cell's axes nest: by role, then as given."""
    params = declared(classes)
    return sorted(names, key=lambda n: rank(params[n]) if n in params else len(ROLES))
