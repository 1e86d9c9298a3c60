"""The lean install and its extras: ``_extras.require``, the package and CLI without any extra (a subprocess to
which every optional library is absent), and that every third-party import of the package is either a core
dependency or goes through ``require`` with an extra of pyproject that installs it."""

from __future__ import annotations

import ast
import functools
import importlib.metadata as metadata
import json
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from bubblecal._extras import DISTRIBUTIONS, EXTRAS, MissingExtraError, require

ROOT = Path(__file__).resolve().parents[1]
#: A wide console: help tables and messages are not cut at 80 columns.
ENV = {**os.environ, "COLUMNS": "200"}
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())
LAYERS = ("data", "priors", "models", "surrogates", "sim", "campaigns", "inference", "workflows")
#: The extras each layer may require (ARCHITECTURE.md: Warp and Dask in sim/campaigns, torch in surrogates.training,
#: SALib behind inference.sensitivity); workflows may use any.
LAYER_EXTRAS = {"data": set(), "priors": set(), "models": set(), "surrogates": {"train"}, "sim": {"sim"},
                "campaigns": {"sim", "cluster"}, "inference": {"sensitivity"}, "workflows": set(EXTRAS)}
#: Every optional library, by import name: absent in the subprocess below.
OPTIONAL = sorted({m for mods in EXTRAS.values() for m in mods} | {"onnx_ir", "rtree"})


def _name(requirement: str) -> str:
    """The normalised distribution name of a requirement string (PEP 503)."""
    return re.sub(r"[-_.]+", "-", re.match(r"[A-Za-z0-9_.-]+", requirement).group(0)).lower()


# -------------------------------------------------------------------------------------------------
# require
# -------------------------------------------------------------------------------------------------
@pytest.fixture
def demo_extra(monkeypatch, tmp_path):
    """An extra 'demo' of three libraries: json (present), one that is absent, one whose own requirement is absent."""
    (tmp_path / "brokenlib_xyz").mkdir()
    (tmp_path / "brokenlib_xyz" / "__init__.py").write_text("import requirement_of_brokenlib_xyz\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setitem(EXTRAS, "demo", ("json", "absentlib_xyz", "brokenlib_xyz"))
    return "demo"


def test_require_returns_the_module(demo_extra):
    import json as json_module

    assert require("json", demo_extra) is json_module
    assert require("json.decoder", demo_extra) is sys.modules["json.decoder"]


def test_require_names_the_extra_and_the_command(demo_extra):
    with pytest.raises(MissingExtraError) as info:
        require("absentlib_xyz.sub", demo_extra)
    err = info.value
    assert isinstance(err, ImportError) and err.name == "absentlib_xyz" and err.extra == "demo"
    assert err.install == "pip install 'bubblecal[demo]'"
    assert "absentlib_xyz is not installed" in str(err) and "[demo] extra" in str(err)
    assert "pip install 'bubblecal[demo]'" in str(err) and "-e '.[demo]'" in str(err)


def test_require_names_the_distribution_where_it_differs():
    assert "warp (warp-lang) is not installed" in str(MissingExtraError("warp", "sim"))
    assert str(MissingExtraError("SALib.sample.sobol", "sensitivity")).startswith("SALib is not installed")


def test_a_broken_installation_keeps_its_own_error(demo_extra):
    with pytest.raises(ModuleNotFoundError) as info:
        require("brokenlib_xyz", demo_extra)
    assert not isinstance(info.value, MissingExtraError) and info.value.name == "requirement_of_brokenlib_xyz"
    with pytest.raises(ModuleNotFoundError) as info:  # an installed library without that submodule
        require("json.no_such_submodule_xyz", demo_extra)
    assert not isinstance(info.value, MissingExtraError)


def test_require_refuses_an_unknown_extra_or_a_library_of_another_extra():
    with pytest.raises(ValueError, match="unknown extra 'simulation'"):
        require("warp", "simulation")
    with pytest.raises(ValueError, match=r"the \[sim\] extra does not install 'torch'"):
        require("torch", "sim")


# -------------------------------------------------------------------------------------------------
# the lean core: a subprocess without any optional library
# -------------------------------------------------------------------------------------------------
_LEAN = '''
import contextlib, io, json, sys
REFUSED = set(sys.argv[1].split(","))


class Hide:
    """A finder of sys.meta_path that does not see the optional libraries: to the import system they are absent
    (import raises ModuleNotFoundError, importlib.util.find_spec returns None, sys.modules has no entry), as
    libraries that probe for an optional one expect (xarray for dask, scipy for torch)."""

    def __init__(self, finder):
        self.finder = finder

    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in REFUSED:
            return None
        return self.finder.find_spec(name, path, target)

    def __getattr__(self, attr):
        return getattr(self.finder, attr)


sys.meta_path[:] = [Hide(finder) for finder in sys.meta_path]
out = {}
import bubblecal, bubblecal.data, bubblecal.priors, bubblecal.models, bubblecal.surrogates, bubblecal.sim
import bubblecal.campaigns, bubblecal.inference, bubblecal.workflows, bubblecal.workflows.cli
import bubblecal.surrogates.training
from bubblecal._extras import MissingExtraError
from bubblecal.workflows.cli import main

out["imported"] = sorted(m for m in sys.modules if m.split(".")[0] in REFUSED)
for key, argv in json.loads(sys.argv[2]).items():
    err, std = io.StringIO(), io.StringIO()
    sys.argv = ["bubblecal", *argv]
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(std):
        try:
            main()
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else int(exc.code is not None)
        except BaseException as exc:
            code = f"{type(exc).__name__}: {exc}"
    out[key] = {"code": code, "stderr": " ".join(err.getvalue().split()), "stdout": std.getvalue()}
try:
    import bubblecal.sim.engine.kernels.pairs
    out["warp_module"] = "imported"
except MissingExtraError as exc:
    out["warp_module"] = exc.extra
print("RESULT " + json.dumps(out))
'''


@pytest.fixture(scope="module")
def lean(tmp_path_factory):
    """Run the package and several commands in one subprocess without any extra; the outputs by case."""
    tmp = tmp_path_factory.mktemp("lean")
    csv = tmp / "curves.csv"
    csv.write_text("not read: the extra is checked first\n")
    cases = {
        "help": ["--help"],
        "calibrate_help": ["calibrate", "--help"],
        "verify": ["sim", "verify", "--quick"],
        "campaign": ["sim", "campaign", "definity_ringdown", "--store", str(tmp / "store"), "--scheduler", "inline"],
        "campaign_dask": ["sim", "campaign", "definity_ringdown", "--store", str(tmp / "store2")],
        "train": ["surrogates", "train", str(csv), "--setup", "compression", "--diameter", "2.1",
                  "--out", str(tmp / "train")],
        "sensitivity": ["sensitivity", "--surrogate", str(tmp / "s.npz"), "--curve", "definity-2.1",
                        "--out", str(tmp / "sens")],
    }
    res = subprocess.run([sys.executable, "-c", _LEAN, ",".join(OPTIONAL), json.dumps(cases)], capture_output=True,
                         text=True, timeout=300, cwd=tmp, env=ENV)
    lines = [line for line in res.stdout.splitlines() if line.startswith("RESULT ")]
    assert res.returncode == 0 and lines, res.stdout[-3000:] + res.stderr[-3000:]
    return json.loads(lines[-1].removeprefix("RESULT ")), tmp


def test_the_package_imports_without_any_extra(lean):
    out, _ = lean
    assert out["imported"] == []


def test_help_and_calibrate_help_without_any_extra(lean):
    out, _ = lean
    assert out["help"]["code"] == 0 and "calibrate" in out["help"]["stdout"]
    assert out["calibrate_help"]["code"] == 0 and "--population" in out["calibrate_help"]["stdout"]


@pytest.mark.parametrize(("case", "extra", "library"), [
    ("verify", "sim", "warp (warp-lang)"), ("campaign", "sim", "warp (warp-lang)"),
    ("campaign_dask", "sim", "distributed"), ("train", "train", "torch"), ("sensitivity", "sensitivity", "SALib")])
def test_a_command_without_its_extra_says_what_to_install(lean, case, extra, library):
    out, _ = lean
    got = out[case]
    assert got["code"] == 1, got
    assert got["stderr"].startswith(f"error: {library} is not installed"), got["stderr"]
    assert f"pip install 'bubblecal[{extra}]'" in got["stderr"] and "Traceback" not in got["stderr"]


def test_a_missing_extra_leaves_no_output_behind(lean):
    """No work is lost and no partial result written: the extra is checked before a store or folder is made."""
    _, tmp = lean
    assert not any((tmp / name).exists() for name in ("store", "store2", "train", "sens"))


def test_a_warp_module_without_the_sim_extra(lean):
    out, _ = lean
    assert out["warp_module"] == "sim"


@pytest.mark.slow
def test_calibrate_runs_without_any_extra(tmp_path):
    """A small staged calibration of one curve on the shipped bundle, in a process without any extra."""
    argv = ["calibrate", "--agent", "definity", "--workflow", "reduced", "--curve", "definity_compression_2.1um",
            "--population", "200", "--phase2-samples", "200", "--mcmc-steps", "2", "--no-figures",
            "--out", str(tmp_path / "cal")]
    res = subprocess.run([sys.executable, "-c", _LEAN, ",".join(OPTIONAL), json.dumps({"run": argv})],
                         capture_output=True, text=True, timeout=1200, cwd=tmp_path, env=ENV)
    lines = [line for line in res.stdout.splitlines() if line.startswith("RESULT ")]
    assert lines, res.stdout[-3000:] + res.stderr[-3000:]
    run = json.loads(lines[-1].removeprefix("RESULT "))["run"]
    assert run["code"] == 0, run
    assert list((tmp_path / "cal" / "definity" / "reduced").glob("phase3_*"))


# -------------------------------------------------------------------------------------------------
# every third-party import is core, or required through an extra that installs it
# -------------------------------------------------------------------------------------------------
def _third_party_imports(path: Path):
    """(top-level import name, extra or None, line) of every import of a library outside the standard library."""
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names, extra = [a.name for a in node.names], None
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names, extra = [node.module], None
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "require":
            literal = len(node.args) == 2 and all(isinstance(a, ast.Constant) for a in node.args)
            assert literal, f"{path}:{node.lineno}: require takes two literal names (the checks read them statically)"
            names, extra = [node.args[0].value], node.args[1].value
        else:
            continue
        for name in names:
            top = name.split(".")[0]
            if top not in sys.stdlib_module_names and top != "bubblecal" and top != "__future__":
                yield top, extra, node.lineno


@functools.cache
def _providers() -> dict[str, list[str]]:
    """Import name -> the installed distributions that provide it."""
    return metadata.packages_distributions()


def _distribution(top: str) -> str:
    """The normalised name of the installed distribution that provides an import name."""
    found = _providers().get(top)
    assert found, f"{top}: no installed distribution provides it (the test runs in the [all] environment)"
    return _name(found[0])


def _optional() -> dict[str, set[str]]:
    """pyproject's extras: extra -> the normalised distribution names it lists."""
    return {extra: {_name(r) for r in reqs} for extra, reqs in PYPROJECT["project"]["optional-dependencies"].items()}


def _package_files():
    files = [p for layer in LAYERS for p in sorted((ROOT / layer).rglob("*.py"))]
    return files + [ROOT / "__init__.py", ROOT / "_lazy.py", ROOT / "_extras.py"]


def test_every_third_party_import_is_core_or_in_its_extra():
    core = {_name(r) for r in PYPROJECT["project"]["dependencies"]}
    optional = _optional()
    problems = []
    for path in _package_files():
        rel = path.relative_to(ROOT)
        layer = rel.parts[0] if len(rel.parts) > 1 else None
        for top, extra, line in _third_party_imports(path):
            where = f"{rel}:{line}: {top}"
            dist = _distribution(top)
            if extra is None:
                if dist not in core:
                    problems.append(f"{where} is not a core dependency: import it with require({top!r}, EXTRA)")
            elif dist not in optional.get(extra, set()):
                problems.append(f"{where}: pyproject's [{extra}] extra does not list {dist}")
            elif layer is not None and extra not in LAYER_EXTRAS[layer]:
                problems.append(f"{where}: the {layer} layer may not require the [{extra}] extra")
    assert not problems, "\n".join(problems)


def test_the_extras_of_pyproject_and_of_the_package_agree():
    optional = _optional()
    for extra, modules in EXTRAS.items():
        for module in modules:
            assert _distribution(module) in optional[extra], f"[{extra}] does not list the distribution of {module}"
            assert _name(DISTRIBUTIONS.get(module, module)) == _distribution(module)
    # [all] is what the test suite needs on a CPU machine: every extra but the CUDA plugin (docs/decisions.md)
    (everything,) = PYPROJECT["project"]["optional-dependencies"]["all"]
    listed = set(re.search(r"\[(.*)\]", everything).group(1).split(","))
    assert _name(everything) == "bubblecal" and listed == set(optional) - {"all", "gpu"}
    assert set(EXTRAS) == set(optional) - {"all", "gpu", "dev"}


def test_the_lock_pins_every_requirement_exactly():
    """requirements.lock pins (name==version) every core and extra requirement, each inside pyproject's range."""
    from packaging.requirements import Requirement

    lock = {}
    for line in (ROOT / "requirements.lock").read_text().splitlines():
        name, _, version = line.partition("==")
        assert version and " " not in line, f"requirements.lock: {line!r} is not name==version"
        lock[_name(name)] = version
    reqs = PYPROJECT["project"]["dependencies"] + [r for extra, rs in PYPROJECT["project"]["optional-dependencies"]
                                                   .items() if extra != "all" for r in rs]
    for text in reqs:
        req = Requirement(text)
        assert _name(req.name) in lock, f"requirements.lock does not pin {req.name}"
        assert req.specifier.contains(lock[_name(req.name)]), f"the lock's {req.name} is outside {req.specifier}"
    assert lock["jax-cuda13-plugin"] == lock["jaxlib"] == lock["jax"]


def test_the_readme_commands_install_the_core_then_all_and_ci_runs_the_second():
    section = (ROOT / "README.md").read_text().split("## The two commands", 1)[1].split("\n## ", 1)[0]
    main_job, suite = re.findall(r"```bash\n(.*?)\n```", section, re.DOTALL)
    assert "-e . &&" in main_job and "[" not in main_job and main_job.endswith("bubblecal calibrate --out calibration")
    assert '-e ".[all]" &&' in suite and suite.endswith("python -m pytest")
    assert suite in (ROOT / ".ci" / "run").read_text().splitlines()


def test_info_names_the_extra_of_each_optional_package(monkeypatch):
    """`bubblecal info` marks a missing optional package with the extra that installs it."""
    from typer.testing import CliRunner

    from bubblecal.workflows import cli_info
    from bubblecal.workflows.cli import app

    assert {name: cli_info._EXTRA_OF.get(name) for name in cli_info._PACKAGES if name in cli_info._EXTRA_OF} == {
        "torch": "train", "warp-lang": "sim", "trimesh": "sim", "onnxruntime": "train", "SALib": "sensitivity",
        "dask": "sim"}
    version = metadata.version

    def without_torch(name):
        if name == "torch":
            raise metadata.PackageNotFoundError(name)
        return version(name)

    monkeypatch.setattr(cli_info.metadata, "version", without_torch)
    monkeypatch.setenv("COLUMNS", "200")
    res = CliRunner().invoke(app, ["info"])
    assert res.exit_code == 0 and "not installed (extra [train])" in res.output
