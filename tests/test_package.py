"""The package's house rules (ARCHITECTURE.md): every folder is a listed subpackage, layers point one way,
modules stay small, package code carries contracts rather than history, and cites only the repository."""

import ast
import importlib
import inspect
import io
import re
import tokenize
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ("data", "priors", "models", "surrogates", "sim", "campaigns", "inference", "workflows")
# what each layer may import from bubblecal (ARCHITECTURE.md); itself always allowed
ALLOWED = {
    "data": set(),
    "priors": {"data"},
    "surrogates": {"data"},
    "sim": {"data"},
    "campaigns": {"sim", "priors", "data"},
    "models": {"surrogates", "priors", "data"},
    "inference": set(),
    "workflows": set(LAYERS),
}
#: Private helpers of the root package that every layer may use (they import nothing of bubblecal).
ROOT_HELPERS = {"_lazy", "_extras", "_progress", "_folders"}
FORBIDDEN_THIRD_PARTY = {
    "data": {"jax", "numpyro", "torch", "warp"},
    "priors": {"jax", "numpyro", "torch", "warp"},
    "sim": {"jax", "numpyro", "torch"},
    "campaigns": {"jax", "numpyro", "torch"},
    "models": {"torch", "warp"},
    "inference": {"torch", "warp"},
}
#: Modules allowed above MAX_LINES, each with the reason: they are Warp kernel sources, where one family of
#: kernels and the functions they share must live in one closure per dtype.
MAX_LINES = 400
LONG_MODULES: dict[str, str] = {}
#: History does not belong in package code: no session or issue numbers, no dated measurements.
HISTORY = re.compile(r"\bsessions?\b|\bissues?\s*#?\d|\bitems?\s+\d|\b20\d\d-\d\d-\d\d\b", re.IGNORECASE)
#: Paths outside the repository.
OUTSIDE = re.compile(r"\.\./|\bshared/(docs|reference|tools)|/work/|/home/|/root/")
#: Repository files cited from package code: they must exist.
CITED = re.compile(r"\b((?:docs|benchmarks|data)/[A-Za-z0-9_./-]+\.(?:md|py|csv|json))\b")


def _python_files(folder):
    return sorted(p for p in (ROOT / folder).rglob("*.py") if ".venv" not in p.parts)


def _package_files():
    return [p for layer in LAYERS for p in _python_files(layer)] + [ROOT / "__init__.py"] + \
        [ROOT / f"{name}.py" for name in ROOT_HELPERS]


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
        elif _is_require(node):  # an optional library: require("warp", "sim") (_extras.py)
            yield node.args[0].value


def _is_require(node) -> bool:
    """Whether ``node`` is a call ``require("module", "extra")`` with literal arguments."""
    return isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "require" \
        and len(node.args) == 2 and all(isinstance(a, ast.Constant) and isinstance(a.value, str) for a in node.args)


def test_root_helpers_import_no_layer():
    for name in ROOT_HELPERS:
        for module in _imports(ROOT / f"{name}.py"):
            assert not module.startswith("bubblecal"), f"{name}.py must not import {module}"


@pytest.mark.parametrize("layer", LAYERS)
def test_layer_directions(layer):
    for path in _python_files(layer):
        for module in _imports(path):
            assert module != "<relative>", f"{path}: import through bubblecal.* (no relative imports)"
            parts = module.split(".")
            if parts[0] == "bubblecal" and len(parts) > 1:
                target = parts[1]
                assert target == layer or target in ALLOWED[layer] or target in ROOT_HELPERS, \
                    f"{path}: {layer} must not import bubblecal.{target}"
            assert parts[0] not in FORBIDDEN_THIRD_PARTY.get(layer, set()), \
                f"{path}: {layer} must not import {parts[0]}"
            assert parts[0] not in LAYERS, f"{path}: import through bubblecal.{parts[0]}, not {parts[0]}"


@pytest.mark.parametrize("folder", ["tests", "benchmarks", "notebooks"])
def test_scripts_import_through_the_package(folder):
    for path in _python_files(folder):
        for module in _imports(path):
            assert module.split(".")[0] not in LAYERS, f"{path}: import through bubblecal.{module}, not {module}"


def test_modules_stay_small():
    too_long = {}
    for path in _package_files():
        rel = str(path.relative_to(ROOT))
        n = len(path.read_text().splitlines())
        if n > MAX_LINES and rel not in LONG_MODULES:
            too_long[rel] = n
    assert not too_long, \
        f"modules over {MAX_LINES} lines (split them, or list a kernel module in LONG_MODULES): {too_long}"
    for rel in LONG_MODULES:
        assert (ROOT / rel).exists(), f"LONG_MODULES lists {rel}, which no longer exists"
        assert len((ROOT / rel).read_text().splitlines()) > MAX_LINES, f"{rel} is short now: drop it from LONG_MODULES"


def test_no_history_in_package_code():
    found = []
    for path in _package_files():
        for k, line in enumerate(path.read_text().splitlines(), start=1):
            if HISTORY.search(line):
                found.append(f"{path.relative_to(ROOT)}:{k}: {line.strip()}")
    assert not found, "history belongs in benchmarks/RESULTS.md or docs/decisions.md:\n" + "\n".join(found)


def _docs_and_comments(path):
    """(line number, text) of every docstring line and comment of a module."""
    source = path.read_text()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
                    and isinstance(body[0].value.value, str):
                for k, line in enumerate(body[0].value.value.splitlines()):
                    yield body[0].lineno + k, line
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.COMMENT:
            yield tok.start[0], tok.string


def test_package_code_cites_only_the_repository():
    found, missing = [], []
    for path in _package_files():
        for k, line in _docs_and_comments(path):
            if OUTSIDE.search(line):
                found.append(f"{path.relative_to(ROOT)}:{k}: {line.strip()}")
            for cited in CITED.findall(line):
                if not (ROOT / cited).exists():
                    missing.append(f"{path.relative_to(ROOT)}:{k}: {cited}")
    assert not found, "paths outside the repository:\n" + "\n".join(found)
    assert not missing, "cited files that do not exist:\n" + "\n".join(missing)


def test_line_length_is_enforced_at_120():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["ruff"]
    assert config["line-length"] <= 120
    assert "E501" not in config.get("lint", {}).get("ignore", [])
    assert "E" in config["lint"]["select"] or "E501" in config["lint"]["select"]


def _public_objects():
    for layer in LAYERS:
        module = importlib.import_module(f"bubblecal.{layer}")
        for name in getattr(module, "__all__", ()):
            yield f"bubblecal.{layer}", name, getattr(module, name)


@pytest.mark.parametrize("layer", LAYERS)
def test_every_layer_has_a_curated_api(layer):
    module = importlib.import_module(f"bubblecal.{layer}")
    exported = getattr(module, "__all__", None)
    assert exported, f"bubblecal.{layer} has no __all__"
    for name in exported:
        assert hasattr(module, name), f"bubblecal.{layer}.__all__ names {name}, which it does not define"
    assert len(set(exported)) == len(exported), f"bubblecal.{layer}.__all__ repeats a name"


def _has_section(doc: str, section: str) -> bool:
    return re.search(rf"^\s*{section}\n\s*-{{3,}}\s*$", doc or "", re.MULTILINE) is not None


def test_public_api_docstrings_are_numpydoc_contracts():
    problems = []
    for where, name, obj in _public_objects():
        if not (inspect.isfunction(obj) or inspect.isclass(obj)):
            continue
        doc = inspect.getdoc(obj) or ""
        if not doc.strip():
            problems.append(f"{where}.{name}: no docstring")
            continue
        if inspect.isfunction(obj):
            params = [p for p in inspect.signature(obj).parameters.values()
                      if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]
            if params and not _has_section(doc, "Parameters"):
                problems.append(f"{where}.{name}: no 'Parameters' section")
        elif not issubclass(obj, BaseException | Warning):
            init_doc = inspect.getdoc(obj.__init__) if "__init__" in vars(obj) else ""
            if not any(_has_section(d, s) for d in (doc, init_doc or "") for s in ("Parameters", "Attributes")):
                problems.append(f"{where}.{name}: no 'Parameters' or 'Attributes' section")
    assert not problems, "public objects without a numpydoc contract:\n" + "\n".join(problems)


def test_the_command_line_starts_without_jax_or_scipy():
    """`bubblecal` imports its commands without JAX, NumPyro or SciPy (the layers export them lazily), so the CLI
    answers --help at once and `calibrate` spawns its worker processes before it imports JAX itself."""
    import subprocess
    import sys

    heavy = ("jax", "numpyro", "scipy", "pandas", "matplotlib", "arviz")
    code = f"import sys, bubblecal.workflows.cli; print(sorted(m for m in {heavy!r} if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def test_lazy_exports_by_module_name_each_export_once():
    """`by_module` inverts {module: names}; a name under two modules is refused, naming both."""
    from bubblecal._lazy import by_module

    assert by_module({"a.b": ("x", "y"), "a.c": ("z",)}) == {"x": "a.b", "y": "a.b", "z": "a.c"}
    with pytest.raises(ValueError, match="x is exported from both a.b and a.c"):
        by_module({"a.b": ("x",), "a.c": ("x",)})
