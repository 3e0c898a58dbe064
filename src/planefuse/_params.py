"""One way to check the fields of the library's parameter dataclasses.

Every parameter class states its rules in ``__post_init__`` with :func:`check_fields`; an error always
reads ``ClassName.field must be <rule>, got <value>``. The run configuration (:mod:`planefuse.config`)
builds these classes while it validates a file and finds the configuration field behind such a message
by the ``ClassName.field`` it names, so each rule is written once, here, and reported at the file's line.
"""

from __future__ import annotations

import math
from typing import Any

__all__ = ["check_fields", "RULES"]

#: Rule name -> (test, wording). Tests get a value that is not None.
RULES: dict[str, tuple[Any, str]] = {
    "finite": (lambda v: math.isfinite(v), "finite"),
    ">0": (lambda v: math.isfinite(v) and v > 0, "finite and > 0"),
    ">=0": (lambda v: math.isfinite(v) and v >= 0, "finite and >= 0"),
    "(0,1)": (lambda v: 0.0 < v < 1.0, "in (0, 1)"),
    "[0,1]": (lambda v: 0.0 <= v <= 1.0, "in [0, 1]"),
    "(0,1]": (lambda v: 0.0 < v <= 1.0, "in (0, 1]"),
    "int>=0": (lambda v: float(v).is_integer() and v >= 0, "an integer >= 0"),
    "int>=1": (lambda v: float(v).is_integer() and v >= 1, "an integer >= 1"),
}


def check_fields(obj: Any, **rules: str) -> None:
    """Raise ``ValueError("Class.field must be <rule>, got <value>")`` for the first field breaking its rule.

    Parameters
    ----------
    obj : dataclass instance
        The parameters being checked (their class name starts the message).
    **rules : str
        Field name -> a key of :data:`RULES`; a leading ``"?"`` also accepts None (``"?>0"``).
    """
    cls = type(obj).__name__
    for name, rule in rules.items():
        value = getattr(obj, name)
        optional = rule.startswith("?")
        if optional and value is None:
            continue
        test, wording = RULES[rule.removeprefix("?")]
        try:
            ok = bool(test(float(value)))
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise ValueError(f"{cls}.{name} must be {'None or ' if optional else ''}{wording}, got {value!r}")


def require(ok: bool, obj: Any, fields: str, message: str) -> None:
    """Raise ``ValueError("Class.fields: message")`` when ``ok`` is False (a rule between several fields;
    ``fields`` names them, the first one is where the configuration reports it)."""
    if not ok:
        raise ValueError(f"{type(obj).__name__}.{fields}: {message}")
