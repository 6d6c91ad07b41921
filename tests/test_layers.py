"""The house's rules (docs/architecture.md, "Layers"): lower layers never import higher ones, no
import circle anywhere (imports inside functions count), no two modules share a file name, and
every package says what it is and exports its public names the same way."""

import ast
from collections import Counter
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "robot_ctrl"
#: Each layer may import its own and lower layers only. A module belongs to the longest key that
#: prefixes its dotted path.
LAYER = {
    "geometry": 0, "modes": 0, "kernels": 0, "lazy_exports": 0, "parent_death": 0,  # the ground floor
    "robot": 1,  # configs → RobotModel
    "hw": 2,  # the hardware interface and the safety layer
    "wpg": 2, "sot": 2, "synthesis": 2,  # pipeline stages
    "sim": 3, "buses": 3,  # backends of the hardware interface: the simulated world, real servo buses
    "crowd": 3, "dynfilter": 3,
    "backends": 4,  # a backend chosen by name (the CLI's --hw), behind the safety layer
    "control": 4, "control.estimation": 4, "control.loop": 4,
    "control.controllers": 5, "control.commanders": 6,
    "eval": 7, "eval.recording": 7, "eval.reports": 8, "eval.campaigns": 9,
    "scenarios": 10, "cli": 11,
}


def _modules() -> dict[str, Path]:
    """Dotted name (without ``robot_ctrl.``; a package by its own name) → file."""
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE).with_suffix("").parts
        if parts[0] == "_data":
            continue
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _layer_key(name: str) -> str | None:
    keys = [k for k in LAYER if name == k or name.startswith(k + ".")]
    return max(keys, key=len) if keys else None


def _imports(path: Path) -> set[str]:
    """The robot_ctrl modules ``path`` imports (``from pkg import module`` names the module)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("robot_ctrl"):
            base = node.module.removeprefix("robot_ctrl").removeprefix(".")
            for alias in node.names:
                sub = f"{base}.{alias.name}" if base else alias.name
                out.add(sub if sub in MODULES else base)
        elif isinstance(node, ast.Import):
            out |= {a.name.removeprefix("robot_ctrl").removeprefix(".") for a in node.names
                    if a.name.startswith("robot_ctrl")}
    return out - {""}


GRAPH = {name: _imports(path) for name, path in MODULES.items()}


def test_no_module_imports_from_a_higher_layer():
    upward = []
    for name in MODULES:
        if not name:
            continue
        key = _layer_key(name)
        assert key is not None, f"robot_ctrl.{name} has no layer: add it to LAYER and docs/architecture.md"
        for other in GRAPH[name]:
            if LAYER[_layer_key(other)] > LAYER[key]:
                upward.append(f"robot_ctrl.{name} imports robot_ctrl.{other}")
    assert not upward, "\n".join(upward)


def test_no_import_circle():
    """Depth-first search for a back edge; a circle is printed as the path that closes it."""
    state, circles = {}, []

    def visit(name, path):
        state[name] = "open"
        for other in sorted(GRAPH.get(name, ())):
            if state.get(other) == "open":
                circles.append(" -> ".join(path[path.index(other):] + [other]))
            elif other not in state:
                visit(other, path + [other])
        state[name] = "done"

    for name in sorted(MODULES):
        if name not in state:
            visit(name, [name])
    assert not circles, "\n".join(circles)


def test_the_circle_finder_finds_a_circle():
    GRAPH["geometry.frames"].add("kernels")
    GRAPH["kernels"].add("geometry.frames")
    try:
        with pytest.raises(AssertionError, match="geometry.frames -> kernels"):
            test_no_import_circle()
    finally:
        GRAPH["geometry.frames"].discard("kernels")
        GRAPH["kernels"].discard("geometry.frames")


def test_no_two_modules_share_a_file_name():
    names = Counter(p.name for p in MODULES.values() if p.name not in ("__init__.py", "__main__.py"))
    assert not [n for n, count in names.items() if count > 1]


def test_no_folder_holds_more_than_twelve_modules():
    folders = Counter(p.parent for p in MODULES.values() if p.name not in ("__init__.py", "__main__.py"))
    assert not {str(f.relative_to(PACKAGE)): n for f, n in folders.items() if n > 12}


def test_every_package_says_what_it_is_and_exports_its_names():
    for name, path in MODULES.items():
        if path.name != "__init__.py":
            continue
        tree = ast.parse(path.read_text())
        assert ast.get_docstring(tree), f"{path} has no docstring"
        if name not in ("control", "eval"):  # folders of subpackages
            text = path.read_text()
            assert "lazy_exports(__name__" in text, f"{path} does not export its names with lazy_exports"


def test_no_exported_name_is_also_a_module_of_its_package():
    """Importing ``pkg.name`` (the module) would replace the exported ``pkg.name`` (the function)."""
    clashes = []
    for name, path in MODULES.items():
        if path.name == "__init__.py":
            package = __import__(f"robot_ctrl.{name}".rstrip("."), fromlist=["_"])
            clashes += [f"{name}.{n}" for n in getattr(package, "__all__", ()) if f"{name}.{n}".lstrip(".") in MODULES]
    assert not clashes


def test_every_public_name_has_its_own_docstring():
    """``robot_ctrl.__all__``: each name says what it is in a docstring of its own (not one a
    dataclass, an enum or a named tuple writes for it, nor one inherited)."""
    import inspect

    import robot_ctrl

    def own(name):
        obj = getattr(robot_ctrl, name)
        doc = obj.__dict__.get("__doc__") if inspect.isclass(obj) else obj.__doc__
        generated = (f"{name}(", "An enumeration.", "Create a collection of name/value pairs.")
        return bool(doc and doc.strip() and not doc.strip().startswith(generated))

    assert not [name for name in robot_ctrl.__all__ if not own(name)]
