"""The package's house rules: every folder is a listed subpackage, and layers point one way."""

import ast
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ("data", "priors", "models", "surrogates", "sim", "inference", "workflows")
# what each layer may import from bubblecal (layout.md); itself always allowed
ALLOWED = {
    "data": set(),
    "priors": {"data"},
    "surrogates": {"data"},
    "sim": {"data"},
    "models": {"surrogates", "priors", "data"},
    "inference": set(),
    "workflows": set(LAYERS),
}
FORBIDDEN_THIRD_PARTY = {
    "sim": {"jax", "numpyro", "torch"},
    "models": {"torch", "warp"},
    "inference": {"torch", "warp"},
}


def _python_files(folder):
    return [p for p in (ROOT / folder).rglob("*.py") if ".venv" not in p.parts]


def test_every_subpackage_is_listed():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    listed = set(config["tool"]["setuptools"]["packages"])
    found = {"bubblecal"}
    for layer in LAYERS:
        for init in (ROOT / layer).rglob("__init__.py"):
            found.add("bubblecal." + ".".join(init.parent.relative_to(ROOT).parts))
    assert found == listed


def _imports(path):
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.module
        elif isinstance(node, ast.ImportFrom) and node.level > 0:
            yield "<relative>"


@pytest.mark.parametrize("layer", LAYERS)
def test_layer_directions(layer):
    for path in _python_files(layer):
        for module in _imports(path):
            assert module != "<relative>", f"{path}: import through bubblecal.* (no relative imports)"
            parts = module.split(".")
            if parts[0] == "bubblecal" and len(parts) > 1:
                target = parts[1]
                assert target == layer or target in ALLOWED[layer], f"{path}: {layer} must not import bubblecal.{target}"
            assert parts[0] not in FORBIDDEN_THIRD_PARTY.get(layer, set()), f"{path}: {layer} must not import {parts[0]}"
            assert parts[0] not in LAYERS, f"{path}: import through bubblecal.{parts[0]}, not {parts[0]}"
