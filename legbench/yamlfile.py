"""YAML files of legbench (scenario, sweep, bench and tolerance files): reading and validation helpers.

One reader (:func:`read_yaml`: the document and its node tree, so errors can
name a line), one safe loader that also reads ``1e-4`` as a float, the
``--set KEY=VALUE`` parser, and the checks every file format uses
(:func:`check_keys`, :func:`number`, :func:`vector`, :func:`integer`), each
raising a :class:`~legbench.exceptions.ScenarioError` naming the file, the key
path, the line and the problem.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

from legbench.exceptions import ScenarioError

__all__ = [
    "Loader",
    "YamlContext",
    "check_keys",
    "integer",
    "keypath",
    "number",
    "parse_overrides",
    "read_yaml",
    "set_key",
    "vector",
    "yaml_compose",
    "yaml_load",
]


class Loader(yaml.SafeLoader):
    """PyYAML's safe loader (no object construction) that also reads ``1e-4`` as a float.

    YAML 1.1 wants a dot in a float (``1.0e-4``); engineers write ``1e-4``.
    """


Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
        |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
        |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
        |[-+]?\.(?:inf|Inf|INF)
        |\.(?:nan|NaN|NAN))$""",
        re.X,
    ),
    list("-+0123456789."),
)


def yaml_load(text: str) -> Any:
    """Parse YAML text safely (see :class:`Loader`)."""
    return yaml.load(text, Loader=Loader)  # noqa: S506 - Loader is a SafeLoader


def yaml_compose(text: str) -> yaml.Node | None:
    """The node tree of YAML text (for line numbers in errors)."""
    return yaml.compose(text, Loader=Loader)


# --------------------------------------------------------------------------- #
# Key paths and checks


class YamlContext:
    """File name and YAML node marks, to name lines in errors (scenario, sweep and tolerance files)."""

    def __init__(self, file: str, root: yaml.Node | None) -> None:
        self.file = file
        self.root = root

    def line(self, path: Sequence[str | int]) -> int | None:
        """Line of the key at ``path`` in the file (1-based), or None if unknown."""
        node = self.root
        line = None
        for key in path:
            if isinstance(node, yaml.MappingNode):
                nxt = None
                for k, v in node.value:
                    if k.value == key:
                        line, nxt = k.start_mark.line + 1, v
                        break
                node = nxt
            elif isinstance(node, yaml.SequenceNode) and isinstance(key, int) and key < len(node.value):
                node = node.value[key]
                line = node.start_mark.line + 1
            else:
                break
            if node is None:
                break
        return line

    def error(self, path: Sequence[str | int], problem: str) -> ScenarioError:
        """The error naming the file, the key path, its line and the problem."""
        return ScenarioError(self.file, keypath(path), problem, self.line(path))


def keypath(path: Sequence[str | int]) -> str:
    """``["events", 2, "t"]`` -> ``"events[2].t"``."""
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out


def check_keys(
    ctx: YamlContext, path: list[str | int], d: Any, allowed: Sequence[str], required: Sequence[str] = ()
) -> None:
    """``d`` is a mapping with only ``allowed`` keys (a near miss is suggested) and every ``required`` one."""
    if not isinstance(d, Mapping):
        raise ctx.error(path, f"expected a mapping, got {type(d).__name__}")
    for k in d:
        if k not in allowed:
            folded = [a for a in allowed if a.lower() == str(k).lower()]
            near = folded or difflib.get_close_matches(str(k), allowed, n=1)
            hint = f"; did you mean '{near[0]}'?" if near else f"; valid keys: {', '.join(allowed)}"
            raise ctx.error([*path, str(k)], f"unknown key{hint}")
    for k in required:
        if k not in d:
            raise ctx.error(path, f"missing required key '{k}'")


def number(ctx: YamlContext, path: list[str | int], v: Any, *, positive: bool = False, nonneg: bool = False) -> float:
    """A finite number (not a bool), optionally > 0 or >= 0."""
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise ctx.error(path, f"expected a number, got {v!r}")
    try:
        x = float(v)
    except OverflowError:
        raise ctx.error(path, f"number too large: {v!r}") from None
    if not math.isfinite(x):
        raise ctx.error(path, f"must be finite, got {v!r}")
    if positive and x <= 0:
        raise ctx.error(path, f"must be > 0, got {v!r}")
    if nonneg and x < 0:
        raise ctx.error(path, f"must be >= 0, got {v!r}")
    return x


def vector(ctx: YamlContext, path: list[str | int], v: Any, n: int = 3) -> tuple[float, ...]:
    """A list of ``n`` numbers (a scalar stands for three equal ones)."""
    if isinstance(v, int | float) and not isinstance(v, bool) and n == 3:
        return (number(ctx, path, v),) * n
    if not isinstance(v, list) or len(v) != n:
        raise ctx.error(path, f"expected a list of {n} numbers, got {v!r}")
    return tuple(number(ctx, [*path, i], x) for i, x in enumerate(v))


def integer(ctx: YamlContext, path: list[str | int], v: Any, minimum: int = 1) -> int:
    """An integer (not a bool) >= ``minimum``."""
    if isinstance(v, bool) or not isinstance(v, int) or v < minimum:
        raise ctx.error(path, f"expected an integer >= {minimum}, got {v!r}")
    return v


def read_yaml(path: str | Path) -> tuple[Any, yaml.Node | None]:
    """A YAML file's document and node tree (for line numbers), or a one-line :class:`ScenarioError`."""
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise ScenarioError(str(path), "", "no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(str(path), "", f"cannot read: {exc}") from None
    try:
        root = yaml_compose(text)
        doc = yaml_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = mark.line + 1 if mark is not None else None
        problem = getattr(exc, "problem", None) or str(exc)
        raise ScenarioError(str(path), "", f"malformed YAML: {problem}", line) from None
    if doc is None:
        raise ScenarioError(str(path), "", "empty file")
    return doc, root


def parse_overrides(items: Sequence[str]) -> dict[str, Any]:
    """``KEY=VALUE`` strings (``--set``) -> {dotted key: YAML value}; ``1e-4`` is a float."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise ScenarioError("--set", item, "expected KEY=VALUE, e.g. backends.<name>.dt=5e-5")
        out[key] = yaml_load(value)
    return out


def set_key(doc: dict[str, Any], dotted: str, value: Any) -> None:
    """Set ``a.b.c`` in a nested dict, creating mappings as needed."""
    parts = dotted.split(".")
    d = doc
    for k in parts[:-1]:
        d = d.setdefault(k, {})
    d[parts[-1]] = value
