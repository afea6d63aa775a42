"""YAML files of legbench (scenario, sweep, bench and tolerance files): reading and validation helpers.

One reader (:func:`read_yaml`: the document and its node tree, so errors can
name a line), one safe loader that also reads ``1e-4`` as a float, the
``--set KEY=VALUE`` parser, and the checks every file format uses
(:func:`check_keys`, :func:`number`, :func:`vector`, :func:`integer`), each
raising a :class:`~legbench.exceptions.ScenarioError` naming the file, the key
path, the line and the problem.
"""

from __future__ import annotations

import argparse
import copy
import difflib
import math
import os
import re
import stat
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

from legbench.exceptions import ScenarioError

__all__ = [
    "LIMITS",
    "Loader",
    "YamlContext",
    "check_keys",
    "check_one_place",
    "file_kind",
    "finite_float",
    "integer",
    "keypath",
    "keys_overlap",
    "limit",
    "number",
    "one_line",
    "other_file",
    "parse_overrides",
    "positive_float",
    "read_bytes",
    "read_yaml",
    "set_key",
    "vector",
    "yaml_compose",
    "yaml_load",
]


#: Size limits checked when a file is read, before any work. Raise one deliberately with the environment
#: variable ``LEGBENCH_LIMITS``, e.g. ``LEGBENCH_LIMITS="ticks=5e7,file_bytes=1e7"``.
LIMITS: dict[str, int] = {
    "file_bytes": 1_000_000,  # size of a YAML file [bytes]
    "yaml_nodes": 200_000,  # values of a YAML document once its aliases are expanded
    "yaml_aliases": 1_000,  # aliases (*name) in a YAML document
    "yaml_depth": 64,  # nesting of mappings and lists
    "ticks": 10_000_000,  # control ticks of one scenario (duration x control_rate)
    "sub_steps": 100_000,  # engine sub-steps per control tick (control period / dt)
    "sweep_points": 10_000,  # points of one sweep (product of its grid sizes)
    "integer": 2**31 - 1,  # largest integer setting (iterations, points): the engines' C int
    # largest magnitude of a number [its unit]: far beyond any physical value of this leg (gains ~1e3, contact
    # stiffness ~1e5 N/m), far below where a product of two overflows a double or an engine's float
    "float_abs": 10**12,
}
#: Smallest magnitude of a non-zero number: below it a value is a subnormal or round-off (write 0), and a
#: product of two underflows to 0.
FLOAT_TINY = 1e-30


def limit(name: str) -> int:
    """The limit ``name`` of :data:`LIMITS`, raised by ``LEGBENCH_LIMITS=name=value,...`` if set.

    Every item of ``LEGBENCH_LIMITS`` is checked whichever limit is asked for, so a bad one is refused at once.

    Raises:
        ScenarioError: ``LEGBENCH_LIMITS`` names a limit that does not exist or one twice, or its value is not a
            whole number >= 1 (a limit of 0 or below would refuse everything, and its message would make no
            sense), or raises ``integer`` past the engines' C int.
    """
    given: dict[str, int] = {}
    for item in os.environ.get("LEGBENCH_LIMITS", "").split(","):
        key, sep, value = item.partition("=")
        if not item.strip():
            continue
        if not sep and key.strip() in LIMITS:
            raise ScenarioError("LEGBENCH_LIMITS", key.strip(), f"no value: write {key.strip()}=N")
        if not sep or key.strip() not in LIMITS:  # a typo would leave the limit as it was
            raise ScenarioError("LEGBENCH_LIMITS", item.strip(), f"unknown limit; known: {', '.join(LIMITS)}")
        try:
            x = float(value)
            n = int(x)
        except (ValueError, OverflowError):
            raise ScenarioError("LEGBENCH_LIMITS", key.strip(), f"expected a number, got {value!r}") from None
        if n < 1 or x != n:  # 1.5 was taken for 1
            raise ScenarioError("LEGBENCH_LIMITS", key.strip(), f"must be a whole number >= 1, got {value!r}")
        if key.strip() in given:  # the last one won
            raise ScenarioError("LEGBENCH_LIMITS", key.strip(), "given twice")
        if key.strip() == "integer" and n > LIMITS["integer"]:  # an iteration count past it wrapped to -1294967296
            raise ScenarioError("LEGBENCH_LIMITS", "integer", f"at most {LIMITS['integer']}, the engines' C int "
                                                              f"(it may only be lowered), got {value!r}")  # fmt: skip
        given[key.strip()] = n
    return given.get(name, LIMITS[name])


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

    def __init__(
        self, file: str, root: yaml.Node | None, overridden: Sequence[str] = (), origin: str = "--set"
    ) -> None:
        self.file = file
        self.root = root
        self.overridden = tuple(overridden)  # dotted keys set by --set: their values are not the file's
        self.origin = origin  # what set them, in the caller's words: --set, the Python API's overrides

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
        """The error naming the file, the key path, its line and the problem; for a value that ``--set``
        replaced, the override (``(from --set KEY)``, ``origin`` naming ``--set``) instead of the file's line
        (which holds the old value). A key above an override's (``backends.*`` of ``--set backends.*.dt=...``)
        is blamed on the override too: the override made or changed it, and the file's line nearest it (its
        parent's) would point at what the user did not write."""
        dotted = ".".join(str(p) for p in path)
        for key in self.overridden:
            if dotted and keys_overlap(dotted, key):
                return ScenarioError(self.file, keypath(path), f"{problem} (from {self.origin} {key})")
        return ScenarioError(self.file, keypath(path), problem, self.line(path))


def keys_overlap(a: str, b: str) -> bool:
    """Two dotted keys that set (part of) the same value: equal, or one a whole-part prefix of the other
    (``physics.contact`` and ``physics.contact.Kp``; not ``gains.K`` and ``gains.Kp``)."""
    return a == b or a.startswith(b + ".") or b.startswith(a + ".")


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
    check_magnitude(x, lambda why: ctx.error(path, why))
    if positive and x <= 0:
        raise ctx.error(path, f"must be > 0, got {v!r}")
    if nonneg and x < 0:
        raise ctx.error(path, f"must be >= 0, got {v!r}")
    return x


def check_magnitude(x: float, error: Any) -> None:
    """Raise ``error(why)`` for a number beyond +-``limit("float_abs")`` or non-zero below :data:`FLOAT_TINY`."""
    big = limit("float_abs")
    if abs(x) > big:
        raise error(f"{x:g} is beyond +-{big:g}, more than any physical value here (limit float_abs)")
    if x != 0.0 and abs(x) < FLOAT_TINY:
        raise error(
            f"{x:g} is below {FLOAT_TINY:g} in magnitude (round-off or a subnormal): write 0 or a physical value"
        )


def vector(ctx: YamlContext, path: list[str | int], v: Any, n: int = 3) -> tuple[float, ...]:
    """A list of ``n`` numbers (a scalar stands for three equal ones)."""
    if isinstance(v, int | float) and not isinstance(v, bool) and n == 3:
        return (number(ctx, path, v),) * n
    if not isinstance(v, list) or len(v) != n:
        what = f"a number or a list of {n} numbers" if n == 3 else f"a list of {n} numbers"
        raise ctx.error(path, f"expected {what}, got {v!r}")
    return tuple(number(ctx, [*path, i], x) for i, x in enumerate(v))


def integer(ctx: YamlContext, path: list[str | int], v: Any, minimum: int = 1) -> int:
    """An integer (not a bool) >= ``minimum`` and at most ``limit("integer")`` (the engines' C int)."""
    if isinstance(v, bool) or not isinstance(v, int) or v < minimum:
        raise ctx.error(path, f"expected an integer >= {minimum}, got {v!r}")
    if v > limit("integer"):
        raise ctx.error(path, f"{v} is more than {limit('integer')}, the largest integer the engines take")
    return v


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


#: Control characters (line breaks among them) as they are escaped in a message: a file name, key or value
#: holding one (``name: "a\nb"``, a path with a newline) must not break the message's one line.
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\u2028\u2029]")


def one_line(text: str) -> str:
    """``text`` on one line: every control character (newline, carriage return, ...) written as its escape
    (``\\n``), so a message that quotes the user's input is still one line."""
    return _CONTROL.sub(lambda m: m.group().encode("unicode_escape").decode("ascii"), str(text))


#: legbench's files by a top-level key only they have: (key, what the file is, the command that takes it).
_FILES_BY_KEY = (("events", "a scenario", "run it with legbench run"),
                 ("studies", "a sweep file", "run it with legbench sweep"),
                 ("frameworks", "a framework file", "run it with legbench reproduce"))  # fmt: skip


def other_file(doc: Any, expected: str) -> str | None:
    """Why ``doc`` (parsed YAML) given where ``expected`` goes (``"a leg parameter file"``) is another of legbench's
    files, by a key only that kind has (a scenario's ``events``, a sweep's ``studies``, a framework file's
    ``frameworks``), in the words of the message, e.g. "is a scenario (it has 'events'), not a leg parameter
    file: run it with legbench run"; None where it has none of them (or is that kind itself)."""
    if not isinstance(doc, Mapping):
        return None
    for key, kind, command in _FILES_BY_KEY:
        if key in doc and kind != expected:
            return f"is {kind} (it has '{key}'), not {expected}: {command}"
    return None


_NUMBER_TAGS = ("tag:yaml.org,2002:int", "tag:yaml.org,2002:float")
#: YAML 1.1 number forms that read as something else than they look: base 60 (``1:30`` is 90), octal
#: (``01750`` is 1000), binary (``0b11`` is 3) and digits grouped by ``_`` (``1_0`` is 10). YAML 1.2 reads none
#: of them as numbers; PyYAML reads all silently. (Hexadecimal without ``_``, ``0x10``, is 16 in both and looks it.)
_BASE60 = re.compile(r"[-+]?[0-9][0-9_]*(?::[0-5]?[0-9])+(?:\.[0-9_]*)?")
_OCTAL = re.compile(r"[-+]?0[0-7_]+")
_BINARY = re.compile(r"[-+]?0b[01_]+")


def _yaml11_number(text: str) -> str:
    """Why the plain scalar ``text`` must not be read as YAML 1.1 reads it ('' if it may)."""
    if "_" in text and text.strip("+-_").lower() in ("", "0b", "0x", "0"):  # 0b_, 0x_: no digit, no number
        return f"{text}: not a number (YAML 1.1 reads it as one with no digits); quote it ('{text}') for text"
    if _BASE60.fullmatch(text):
        value = yaml_load(text)
        return (f"{text}: YAML 1.1 reads this as the base-60 number {value!r}; write {value!r} if that is meant, "
                f"or quote it ('{text}') for text")  # fmt: skip
    if _OCTAL.fullmatch(text) and text.lstrip("+-").strip("0_"):
        value = yaml_load(text)
        plain = text.lstrip("+-").lstrip("0_") or "0"
        octal = f", {value!r} for the octal one" if str(value) != plain else ""
        return (f"{text}: YAML 1.1 reads a leading 0 as octal ({value!r}); write {plain} for the decimal "
                f"number{octal}, or quote it ('{text}') for text")  # fmt: skip
    if _BINARY.fullmatch(text):
        value = yaml_load(text)
        return (f"{text}: YAML 1.1 reads this as the binary number {value!r}; write {value!r} if that is meant, "
                f"or quote it ('{text}') for text")  # fmt: skip
    if "_" in text:  # hexadecimal too: YAML 1.2 reads 0x1_0 as text
        value = yaml_load(text)
        return (f"{text}: YAML 1.1 drops the '_' and reads {value!r}; write {value!r} if that is meant, "
                f"or quote it ('{text}') for text")  # fmt: skip
    return ""


def _check_tree(file: str, root: yaml.Node) -> None:
    """Depth, alias count, expanded size and duplicate keys of a composed (not yet expanded) node tree.

    An alias shares its anchor's node in the composed tree, so each node's expanded size is computed
    once (memoised): a billion-laughs document is refused without being expanded.
    """
    max_depth, max_nodes, max_aliases = limit("yaml_depth"), limit("yaml_nodes"), limit("yaml_aliases")
    size: dict[int, int] = {}  # expanded size of a finished node; -1 while its children are visited
    aliases = 0

    def fail(node: yaml.Node, problem: str) -> ScenarioError:
        return ScenarioError(file, "", problem, node.start_mark.line + 1)

    path_of: dict[int, list[str | int]] = {id(root): []}  # a node's key path from the root, for the errors naming it
    stack: list[tuple[yaml.Node, int, bool]] = [(root, 1, False)]
    while stack:
        node, depth, done = stack.pop()
        if isinstance(node, yaml.SequenceNode):
            children = list(node.value)
        elif isinstance(node, yaml.MappingNode):
            children = [n for kv in node.value for n in kv]
        else:
            children = []
        if isinstance(node, yaml.ScalarNode) and node.style is None and node.tag in _NUMBER_TAGS:
            why = _yaml11_number(node.value)
            if why:
                raise ScenarioError(file, keypath(path_of.get(id(node), [])), why, node.start_mark.line + 1)
        if isinstance(node, yaml.ScalarNode) and _SURROGATE.search(node.value):  # "\ud800": not UTF-8
            raise fail(node, f"{node.value!r}: a lone surrogate (a \\u escape of half a character) cannot be "
                             "written as UTF-8 text")  # fmt: skip
        if done:
            size[id(node)] = 1 + sum(size[id(c)] for c in children)
            if size[id(node)] > max_nodes:
                raise fail(node, f"more than {max_nodes} values once its aliases are expanded (limit yaml_nodes)")
            continue
        if id(node) in size:
            if size[id(node)] < 0:
                raise fail(node, "an alias refers to a node that contains it (recursive alias)")
            aliases += 1
            if aliases > max_aliases:
                raise fail(node, f"more than {max_aliases} aliases (limit yaml_aliases)")
            continue
        if depth > max_depth:
            raise fail(node, f"nested more than {max_depth} levels deep (limit yaml_depth)")
        if isinstance(node, yaml.MappingNode):
            seen: dict[Any, int] = {}
            for k, v in node.value:
                if isinstance(k, yaml.ScalarNode):
                    path_of.setdefault(id(v), [*path_of.get(id(node), []), str(k.value)])
                if isinstance(k, yaml.ScalarNode) and k.value != "<<":
                    if k.value in seen:
                        raise ScenarioError(file, keypath([*path_of.get(id(node), []), str(k.value)]),
                                            f"duplicate key (first at line {seen[k.value]})",
                                            k.start_mark.line + 1)  # fmt: skip
                    seen[k.value] = k.start_mark.line + 1
        elif isinstance(node, yaml.SequenceNode):
            for i, item in enumerate(node.value):
                path_of.setdefault(id(item), [*path_of.get(id(node), []), i])
        size[id(node)] = -1
        stack.append((node, depth, True))
        stack.extend((c, depth + 1, False) for c in reversed(children))


#: A lone surrogate code point: YAML's "\ud800" escape loads as one, and no output file can hold it (UTF-8).
_SURROGATE = re.compile("[\ud800-\udfff]")

_OPEN = (yaml.FlowSequenceStartToken, yaml.FlowMappingStartToken, yaml.BlockSequenceStartToken,
         yaml.BlockMappingStartToken)  # fmt: skip
_CLOSE = (yaml.FlowSequenceEndToken, yaml.FlowMappingEndToken, yaml.BlockEndToken)


def _check_depth(file: str, text: str) -> None:
    """Refuse nesting deeper than ``limit("yaml_depth")`` from the token stream, before the (recursive) composer."""
    depth, max_depth = 0, limit("yaml_depth")
    for tok in yaml.scan(text, Loader=Loader):
        if isinstance(tok, _OPEN):
            depth += 1
            if depth > max_depth:
                raise ScenarioError(file, "", f"nested more than {max_depth} levels deep (limit yaml_depth)",
                                    tok.start_mark.line + 1)  # fmt: skip
        elif isinstance(tok, _CLOSE):
            depth -= 1


#: Parsed documents by (file, text): a sweep loads its scenario once per grid point and a study once per run;
#: the YAML is scanned, composed and loaded once, each caller gets its own copy of the document.
#: The key holds ``LEGBENCH_LIMITS`` too: a document is checked against the limits in force when it is read.
_PARSED: dict[tuple[str, str, str], tuple[Any, yaml.Node | None]] = {}
_PARSED_MAX = 64


def parse_text(text: str, file: str) -> tuple[Any, yaml.Node | None]:
    """YAML text's document and node tree, checked against the limits and for duplicate keys, before the
    aliases are expanded; a one-line :class:`ScenarioError` naming ``file`` and the line.

    The document is the caller's own (a deep copy: overrides may change it); the node tree, which only
    gives line numbers, is shared and must not be changed. Only documents that parsed are remembered.
    """
    key = (file, text, os.environ.get("LEGBENCH_LIMITS", ""))
    hit = _PARSED.get(key)
    if hit is None:
        hit = _parse_text(text, file)
        if len(_PARSED) >= _PARSED_MAX:
            _PARSED.pop(next(iter(_PARSED)))
        _PARSED[key] = hit
    doc, root = hit
    return copy.deepcopy(doc), root


def _parse_text(text: str, file: str) -> tuple[Any, yaml.Node | None]:
    if "\x00" in text:
        nul_line = text[: text.index("\x00")].count("\n") + 1
        raise ScenarioError(file, "", "NUL byte in a text file", nul_line)
    try:
        _check_depth(file, text)
        root = yaml_compose(text)
        if root is not None:
            _check_tree(file, root)
        doc = yaml_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = mark.line + 1 if mark is not None else None
        problem = getattr(exc, "problem", None) or str(exc)
        raise ScenarioError(file, "", f"malformed YAML: {_one_line(problem)}", line) from None
    except ValueError as exc:  # a scalar YAML cannot convert: an integer of more than 4300 digits, a bad date
        problem = str(exc).split("; use sys.")[0]  # not Python's own advice
        raise ScenarioError(file, "", f"a value YAML cannot convert: {_one_line(problem)}") from None
    except RecursionError:
        raise ScenarioError(
            file, "", f"nested more than {limit('yaml_depth')} levels deep (limit yaml_depth)"
        ) from None
    return doc, root


#: What a path is, by its ``stat`` mode (:func:`file_kind`).
_KINDS = ((stat.S_ISREG, "a regular file"), (stat.S_ISDIR, "a directory"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISFIFO, "a FIFO"), (stat.S_ISSOCK, "a socket"))  # fmt: skip


def file_kind(mode: int) -> str:
    """What a path of ``stat`` mode ``mode`` is, in words (``a FIFO``, ``a character device``, ...)."""
    return next((name for test, name in _KINDS if test(mode)), "a special file")


def _not_regular(path: Path, mode: int, what: str) -> ScenarioError:
    return ScenarioError(str(path), "", f"is {file_kind(mode)}, not a regular file (a {what} is read only from one)")


def read_bytes(path: str | Path, what: str = "file") -> bytes:
    """The content of a regular file no larger than ``limit("file_bytes")``, or a one-line :class:`ScenarioError`.

    Only a regular file is read (a device such as ``/dev/zero`` has no end, a FIFO blocks until a writer
    comes): its type is checked before it is opened, and again on the open file (opened without blocking, so a
    path swapped for a FIFO in between cannot hang); at most ``limit + 1`` bytes are read, whatever its size
    said.
    """
    path = Path(path)
    cap = limit("file_bytes")
    try:
        mode = os.stat(path).st_mode
        if stat.S_ISDIR(mode):
            raise ScenarioError(str(path), "", f"is a directory, not a {what}")
        if not stat.S_ISREG(mode):
            raise _not_regular(path, mode, what)
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
        with os.fdopen(fd, "rb") as fh:
            st = os.fstat(fh.fileno())
            if not stat.S_ISREG(st.st_mode):
                raise _not_regular(path, st.st_mode, what)
            if st.st_size > cap:
                raise ScenarioError(str(path), "", f"{st.st_size} bytes is more than {cap} (limit file_bytes)")
            data = fh.read(cap + 1)
        if len(data) > cap:  # a file that grew, or one whose size stat does not tell (/proc)
            raise ScenarioError(str(path), "", f"more than {cap} bytes (limit file_bytes)")
        return data
    except FileNotFoundError:
        raise ScenarioError(str(path), "", "no such file") from None
    except OSError as exc:
        raise ScenarioError(str(path), "", f"cannot read: {exc.strerror or exc}") from None


def read_text(path: str | Path, what: str = "file") -> str:
    """A UTF-8 text file read as :func:`read_bytes` reads it, or a one-line :class:`ScenarioError`."""
    data = read_bytes(path, what)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ScenarioError(str(path), "", f"not UTF-8 text (byte {exc.start})") from None


def read_yaml(path: str | Path) -> tuple[Any, yaml.Node | None]:
    """A YAML file's document and node tree (for line numbers), or a one-line :class:`ScenarioError`.

    The file's size, nesting, aliases and duplicate keys are checked before its aliases are expanded.
    """
    doc, root = parse_text(read_text(path), str(path))
    if doc is None:
        raise ScenarioError(str(path), "", "empty file")
    return doc, root


def parse_overrides(items: Sequence[str]) -> dict[str, Any]:
    """``KEY=VALUE`` strings (``--set``) -> {dotted key: YAML value}; ``1e-4`` is a float."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key or any(not p for p in key.split(".")):
            raise ScenarioError("--set", item, "expected KEY=VALUE, e.g. backends.<name>.dt=5e-5")
        try:
            doc, _ = parse_text(value, "--set")
        except ScenarioError as exc:
            raise ScenarioError("--set", key, f"value {value!r}: {exc.problem}") from None
        out[key] = doc
    return out


_ABSENT = object()


def check_one_place(overrides: Mapping[str, Any], given: Mapping[str, str | None], origin: str = "--set") -> None:
    """Refuse a value given both by ``--set`` and by the option that sets it (``given``: dotted key -> the option
    as typed, None where it was not given; ``--set physics.contact_mode=reference --contact-mode native`` ran
    native): one of the two would win in silence.

    Raises:
        ScenarioError: naming the ``--set`` key (or the mapping holding it) and the option; its file is ``origin``
            (the Python API's ``overrides``).
    """
    for key, option in given.items():
        for k, v in overrides.items():
            if option is None or not keys_overlap(k, key):
                continue
            rest = key[len(k) + 1 :].split(".") if len(key) > len(k) else []
            for part in rest:  # a mapping above the key (--set physics={...}) sets it only if it holds it
                v = v.get(part, _ABSENT) if isinstance(v, Mapping) else _ABSENT
            if v is not _ABSENT:
                raise ScenarioError(origin, k, f"also given by {option}; give it in one place")


def set_key(doc: dict[str, Any], dotted: str, value: Any, origin: str = "--set") -> None:
    """Set ``a.b.c`` (``events.0.t``: a list index) in a nested document, creating mappings as needed.

    Raises:
        ScenarioError: a part of the path is a value, not a mapping or list, an index is out of range, or the
            key writes a list index in brackets (``events[0].t``: the error messages' notation); its file is
            ``origin``, what the key came from in the caller's words (``--set``, the Python API's ``overrides``).
    """
    if re.search(r"\[\s*-?\d+\s*\]", dotted):  # events[0].t: the error messages' notation, not --set's
        dots = re.sub(r"\[\s*(-?\d+)\s*\]", r".\1", dotted)
        raise ScenarioError(origin, dotted, f"a list item is written with a dot: {dots}")
    parts = dotted.split(".")
    d: Any = doc
    for i, k in enumerate(parts):
        last = i == len(parts) - 1
        if isinstance(d, list):
            if not k.lstrip("-").isdigit() or not -len(d) <= int(k) < len(d):
                raise ScenarioError(origin, dotted, f"'{'.'.join(parts[:i])}' is a list of {len(d)}: "
                                    f"'{k}' is not an index of it")  # fmt: skip
            if last:
                d[int(k)] = value
            else:
                d = d[int(k)]
        elif isinstance(d, dict):
            if last:
                d[k] = value
            else:
                d = d.setdefault(k, {})
        else:
            raise ScenarioError(origin, dotted, f"'{'.'.join(parts[:i])}' is {d!r}, not a mapping")


def finite_float(text: str) -> float:
    """A command-line number (argparse ``type``): finite, or argparse's one-line error (exit status 2)."""
    try:
        x = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(x):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return x


def physical_float(text: str) -> float:
    """A command-line number that must be finite and within the files' magnitude limits (:func:`check_magnitude`:
    a joint angle of 1e308 rad is no pose), or argparse's one-line error (exit status 2)."""
    x = finite_float(text)

    def refuse(why: str) -> None:
        raise argparse.ArgumentTypeError(why)

    check_magnitude(x, refuse)
    return x


def positive_float(text: str) -> float:
    """A command-line number that must be finite and > 0 (durations, scale factors)."""
    x = finite_float(text)
    if x <= 0.0:
        raise argparse.ArgumentTypeError(f"{text!r} must be > 0")
    return x
