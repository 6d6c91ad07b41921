"""Lower layers never import higher ones (docs/architecture.md, "Layers")."""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "robot_ctrl"
LAYER = {"geometry": 0, "modes": 0, "kernels": 0, "robot": 1, "hw": 1, "wpg": 2, "sot": 2, "synthesis": 2,
         "crowd": 3, "dynfilter": 3, "control": 4, "eval": 4, "scenarios": 5, "cli": 6}


def test_no_module_imports_from_a_higher_layer():
    upward = []
    for path in PACKAGE.rglob("*.py"):
        top = path.relative_to(PACKAGE).with_suffix("").parts[0]
        if top in ("__init__", "_data"):
            continue
        assert top in LAYER, f"{top} has no layer: add it to LAYER and docs/architecture.md"
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("robot_ctrl."):
                other = node.module.split(".")[1]
                if LAYER[other] > LAYER[top]:
                    upward.append(f"{path.relative_to(PACKAGE.parent)} imports {node.module}")
    assert not upward, "\n".join(upward)
