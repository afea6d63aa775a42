"""docs/architecture.md's import rules, checked against every import statement in legbench/.

The order of "What may import what" is read from the document itself, so the document and the
code cannot drift apart: a module imports only modules listed above it (module level or inside a
function), except the upward imports its line names; no module outside ``backends/`` imports an
engine or names one in code; no private name crosses modules; every module has its row in the
document's tables.
"""

from __future__ import annotations

import ast
import re
from dataclasses import dataclass
from pathlib import Path

import pytest

from legbench import backends

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "legbench"
DOC = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")

#: Import names of the engines (and of the symbolic model's algebra), by backend.
ENGINE_IMPORTS = {"pinocchio", "mujoco", "pybullet", "pybullet_data", "pydrake", "dartpy", "odepy", "sympy"}
#: Outside backends/: the leg's reference model is built with Pinocchio (docs/architecture.md's first rule).
REFERENCE_MODEL_MODULES = {"legbench.model": {"pinocchio"}, "legbench.contact": {"pinocchio"}}
#: The one place outside backends/ that names an engine in code.
ENGINE_NAME_ALLOWED = {("legbench.scenario", "DEFAULT_REFERENCE")}


@dataclass(frozen=True)
class Import:
    """One import statement's target in legbench (or a third-party top-level package)."""

    source: str  # importing module, dotted
    target: str  # imported module, dotted (a name imported from a module counts as that module)
    names: tuple[str, ...]  # names taken with `from x import a, b`
    line: int


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


MODULES = {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def source(name: str) -> str:
    return MODULES[name].read_text(encoding="utf-8")


def imports_of(name: str, text: str | None = None) -> list[Import]:
    """Every import statement of module ``name`` (or of ``text`` as that module), at any depth."""
    path = MODULES[name]
    tree = ast.parse(source(name) if text is None else text, filename=str(path))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [Import(name, a.name, (), node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*up, base] if base else up)
            names = tuple(a.name for a in node.names)
            submodules = [f"{base}.{n}" for n in names if f"{base}.{n}" in MODULES]
            if submodules:  # `from legbench import run, report`: each a module
                out += [Import(name, m, (m.rpartition(".")[2],), node.lineno) for m in submodules]
                names = tuple(n for n in names if f"{base}.{n}" not in MODULES)
                if not names:
                    continue
            out.append(Import(name, base, names, node.lineno))
    return out


def documented_order() -> tuple[list[str], dict[str, set[str]]]:
    """The module list of "What may import what" (dotted names) and each line's allowed upward imports."""
    section = DOC.split("## What may import what", 1)[1]
    block = re.search(r"```text\n(.*?)```", section, re.S)
    assert block, "docs/architecture.md: no ```text block under 'What may import what'"
    order, upward = [], {}
    for line in block.group(1).splitlines():
        if not line.strip():
            continue
        entry, _, note = line.partition("(")
        mod = entry.strip()
        mod = "legbench" if mod == "legbench" else f"legbench.{mod}"
        order.append(mod)
        upward[mod] = {f"legbench.{m}" for m in re.findall(r"imports ([\w.]+) inside a function", note)}
    return order, upward


def slot(name: str, order: list[str]) -> int:
    """Position of module ``name`` in the documented order (an engine module takes `backends.<engine>_`'s)."""
    if name in order:
        return order.index(name)
    if re.fullmatch(r"legbench\.backends\.\w+_", name):
        return order.index("legbench.backends.<engine>_")
    raise AssertionError(f"docs/architecture.md: {name} is not in 'What may import what'")


def test_every_module_is_listed_once_in_the_import_order() -> None:
    order, _ = documented_order()
    assert len(order) == len(set(order)), "a module is listed twice"
    for name in MODULES:
        if name == "legbench.studies":  # the namespace of the studies: no code of its own
            continue
        slot(name, order)
    listed = {m for m in order if "<engine>" not in m}
    assert listed <= set(MODULES), f"listed but not in legbench/: {sorted(listed - set(MODULES))}"


def test_every_module_has_its_row_in_the_tables() -> None:
    rows = set(re.findall(r"^\| `([^`]+)` \|", DOC, re.M))
    for name, path in MODULES.items():
        if path.name == "__init__.py" and name != "legbench.backends":
            continue  # the packages themselves; legbench/__init__ is `api`'s entry, said on its row
        rel = path.relative_to(PACKAGE).as_posix()
        key = rel.removeprefix("studies/") if rel.startswith("studies/") else rel
        if re.fullmatch(r"backends/\w+_\.py", key):
            key = "backends/<engine>_.py"
        assert key in rows, f"docs/architecture.md has no table row for {rel}"


def upward_imports(name: str, text: str | None = None) -> list[str]:
    """The legbench imports of ``name`` that target a module not listed above it (nor allowed on its line)."""
    order, upward = documented_order()
    here = slot(name, order)
    out = []
    for imp in imports_of(name, text):
        if imp.target == name or imp.target not in MODULES or imp.target == "legbench.studies":
            continue  # third-party, or `from legbench.studies import x` (recorded as x)
        if slot(imp.target, order) >= here and imp.target not in upward.get(name, set()):
            out.append(f"{MODULES[name].relative_to(ROOT)}:{imp.line} imports {imp.target}, listed below it")
    return out


def engine_imports(name: str, text: str | None = None) -> list[str]:
    """Engine packages imported by ``name`` (outside backends/; Pinocchio allowed where the reference model is)."""
    allowed = REFERENCE_MODEL_MODULES.get(name, set())
    return [
        f"{MODULES[name].relative_to(ROOT)}:{imp.line} imports the engine package {imp.target}"
        for imp in imports_of(name, text)
        if imp.target.partition(".")[0] in ENGINE_IMPORTS - allowed
    ]


@pytest.mark.parametrize("name", sorted(set(MODULES) - {"legbench.studies"}))
def test_imports_go_only_upward(name: str) -> None:
    """Each legbench import of ``name`` targets a module listed above it, or one its line allows."""
    assert upward_imports(name) == []


@pytest.mark.parametrize("name", sorted(m for m in MODULES if not m.startswith("legbench.backends")))
def test_no_engine_outside_the_backends(name: str) -> None:
    """Outside backends/ no engine package is imported (Pinocchio only where the reference model is built)."""
    assert engine_imports(name) == []


def _docstring_nodes(tree: ast.Module) -> set[int]:
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                out.add(id(first.value))
    return out


def engine_names(name: str, text: str | None = None) -> list[str]:
    """Strings in the code of ``name`` (docstrings aside) that are a built-in backend's name."""
    engines = set(backends.BUILTIN)
    tree = ast.parse(source(name) if text is None else text)
    docstrings = _docstring_nodes(tree)
    allowed_nodes = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            if any(isinstance(t, ast.Name) and (name, t.id) in ENGINE_NAME_ALLOWED for t in targets):
                allowed_nodes |= {id(n) for n in ast.walk(node)}
    return [
        f"{MODULES[name].relative_to(ROOT)}:{node.lineno} names the engine {node.value!r}"
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant)
        and isinstance(node.value, str)
        and node.value.lower() in engines
        and id(node) not in docstrings
        and id(node) not in allowed_nodes
    ]


@pytest.mark.parametrize("name", sorted(m for m in MODULES if not m.startswith("legbench.backends")))
def test_no_engine_named_outside_the_backends(name: str) -> None:
    """No string in code outside backends/ is a backend's name, but the default reference's setting."""
    assert engine_names(name) == []


#: Modules whose text goes into reports and comparisons: no engine is named in any string of their code, prose
#: included (an engine's specifics belong to its backend class; their docstrings may name one).
ENGINE_FREE_TEXT = ("legbench.compare", "legbench.report", "legbench.results")


def engine_words(name: str, text: str | None = None) -> list[str]:
    """Strings in the code of ``name`` (docstrings aside) with a built-in backend's name (or Bullet's) as a word."""
    words = re.compile(r"\b(" + "|".join(sorted({*backends.BUILTIN, "bullet"})) + r")\b", re.IGNORECASE)
    tree = ast.parse(source(name) if text is None else text)
    docstrings = _docstring_nodes(tree)
    return [
        f"{MODULES[name].relative_to(ROOT)}:{node.lineno} names {m.group(0)!r}: {node.value[:80]!r}"
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings
        and (m := words.search(node.value))
    ]  # fmt: skip


@pytest.mark.parametrize("name", ENGINE_FREE_TEXT)
def test_no_engine_named_in_report_text(name: str) -> None:
    """report.py's text named engines in code (a residuals caption calling DART's contact a pyramid after DART's
    matched profile took a friction cone; MuJoCo's and Bullet's model settings in the profiles paragraph; the
    reference model as Pinocchio's): the string test above catches only a string that is a backend's name."""
    assert engine_words(name) == []


def private_imports(name: str, text: str | None = None) -> list[str]:
    """The private names (one leading underscore; dunders are public) ``name`` imports from another legbench
    module."""
    out = []
    for imp in imports_of(name, text):
        if imp.target.startswith("legbench"):
            private = [n for n in imp.names if n.startswith("_") and not n.startswith("__")]
            if private:
                out.append(f"{MODULES[name].relative_to(ROOT)}:{imp.line} imports {private} from {imp.target}")
    return out


@pytest.mark.parametrize("name", sorted(MODULES))
def test_no_private_name_crosses_modules(name: str) -> None:
    assert private_imports(name) == []


def test_the_checks_can_fail() -> None:
    """Each check finds the violation planted in a copy of a module's source."""
    planted = source("legbench.model") + "\n\ndef f():\n    from legbench import report\n"
    assert len(upward_imports("legbench.model", planted)) == 1
    assert len(upward_imports("legbench.resources", source("legbench.resources"))) == 0  # its allowed upward import
    assert len(upward_imports("legbench.jit", "from legbench import model\n")) == 1
    assert len(engine_imports("legbench.metrics", "import mujoco\n")) == 1
    assert len(engine_imports("legbench.model", "import pinocchio as pin\n")) == 0
    assert len(engine_names("legbench.metrics", 'REF = "mujoco"\n')) == 1
    assert len(engine_names("legbench.scenario", 'DEFAULT_REFERENCE = "pinocchio"\n')) == 0
    assert len(engine_words("legbench.report", "X = \"a pyramid (DART's and ODE's contact)\"\n")) == 1
    assert len(engine_words("legbench.report", 'def f():\n    """MuJoCo\'s docs may."""\n')) == 0
    # a private name taken from another module, at module level, inside a function, relatively, or from the package
    planted = source("legbench.metrics") + "\n\nfrom legbench.model import _private_thing\n"
    assert private_imports("legbench.metrics", planted) == [
        f"legbench/metrics.py:{len(planted.splitlines())} imports ['_private_thing'] from legbench.model"
    ]
    assert len(private_imports("legbench.metrics", "def f():\n    from legbench.model import load_params, _x\n")) == 1
    assert len(private_imports("legbench.metrics", "from .model import _x\n")) == 1
    assert len(private_imports("legbench.metrics", "from legbench import _x\n")) == 1
    assert len(private_imports("legbench.metrics", "from legbench.model import __all__, load_params\n")) == 0
    assert len(private_imports("legbench.metrics", "from numpy import _NoValue\n")) == 0  # not legbench's
