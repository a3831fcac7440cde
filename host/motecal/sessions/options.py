"""The parts of an import option that names sensors: ``"a=1,b=2"``, a list
of such strings (the option repeated) or a dict -> ``["a=1", "b=2"]``."""
from __future__ import annotations


def option_parts(value) -> list[str]:
    """Non-empty, stripped comma-separated parts of a str, a list of str or a
    dict (``{k: v}`` -> ``"k=v"``); None gives none."""
    if value is None:
        return []
    if isinstance(value, dict):
        items = [f"{k}={v}" for k, v in value.items()]
    elif isinstance(value, str):
        items = [value]
    else:
        items = list(value)
    return [p.strip() for item in items for p in str(item).split(",") if p.strip()]
