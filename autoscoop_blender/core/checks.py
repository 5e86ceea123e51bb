"""Numbers and keys read from users' files, checked: one-line InputErrors that name
the key, the fault and the limits (shared by the sensors file, sensor models and the
settings schema)."""

from __future__ import annotations

import difflib
import math
from collections.abc import Collection, Mapping
from typing import Any

from .errors import InputError


def brief(value: Any, limit: int = 40) -> str:
    """``repr(value)`` on one line, cut to about ``limit`` characters, for messages."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 64:
        return f"a {_digits(value)}-digit {'negative ' if value < 0 else ''}integer"
    try:
        text = repr(value)
    except (RecursionError, ValueError):
        text = f"<{type(value).__name__}>"
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _digits(value: int) -> str:
    """Decimal digits of a (huge) integer, without converting it to text."""
    if value.bit_length() <= 14_000:  # under Python's 4,300-digit str() limit
        return f"{len(str(abs(value))):,}"
    return f"{math.floor(abs(value).bit_length() * math.log10(2)):,}-or-more"


def number(
    value: Any,
    name: str,
    label: str,
    lo: float = -math.inf,
    hi: float = math.inf,
    why: str = "",
) -> float:
    """``value`` as a finite float in [lo, hi], or InputError naming ``name``, the
    fault and the limits (``why`` is appended to an out-of-range message).

    Integers of any size are taken (JSON and TOML give Python ints of any length)
    and refused as too large when no float holds them; bools are not numbers here.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{label}: {name} must be a number, got {brief(value)}")
    try:
        f, huge = float(value), False
    except OverflowError:
        f, huge = (math.inf if value > 0 else -math.inf), True
    if not huge and not math.isfinite(f):
        overflow = "; 1e309 and beyond overflow to inf" if math.isinf(f) else ""
        raise InputError(f"{label}: {name} is {f} (must be a finite number{overflow})")
    shown = f"is {brief(value)}; it" if huge else f"{f:g}"
    if not lo <= f <= hi:
        if lo == -math.inf:
            bound = f"at most {hi:,g}"
        elif hi == math.inf:
            bound = f"at least {lo:,g}"
        else:
            bound = f"in [{lo:,g}, {hi:,g}]"
        raise InputError(f"{label}: {name} {shown} must be {bound}{why}")
    if huge:  # only reached without limits
        raise InputError(f"{label}: {name} is {brief(value)}, too large for a number")
    return f


def whole_number(
    value: Any,
    name: str,
    label: str,
    lo: float = -math.inf,
    hi: float = math.inf,
    why: str = "",
) -> int:
    """``value`` as an int in [lo, hi]: an integer, or a float with an integral value
    (2.0); InputError as ``number``, or for a fraction (1.9)."""
    f = number(value, name, label, lo, hi, why)
    if isinstance(value, int):
        return value
    if not f.is_integer():
        raise InputError(f"{label}: {name} must be a whole number, got {f:g}")
    return int(f)


def check_keys(data: Mapping[Any, Any], known: Collection[str], label: str, what: str) -> None:
    """InputError naming every key of ``data`` not in ``known``: each with the closest
    known key ("did you mean ...?"), and the known keys when one has none."""
    unknown = [k for k in data if k not in known]
    if not unknown:
        return
    parts, lost = [], False
    for key in unknown:
        close = difflib.get_close_matches(str(key), sorted(known), n=1)
        lost = lost or not close
        parts.append(f"{brief(key)} (did you mean {close[0]!r}?)" if close else brief(key))
    s = "s" if len(unknown) > 1 else ""
    known_list = f"; known: {', '.join(sorted(known))}" if lost else ""
    raise InputError(f"{label}: unknown {what} key{s} {', '.join(parts)}{known_list}")
