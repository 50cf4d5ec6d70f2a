"""The import rules of CONTRIBUTING.md, checked on the source (ast), so a violation fails CI.

repro may import everything; experiments imports method and scenes; method and scenes never import
each other, experiments or repro; nothing imports repro; method imports no renderer, plotting or
file-I/O library. defocus_cache (atomic writes, caches, cache keys) imports no project package and is used by
every layer but method.
"""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: Project packages each package must not import.
FORBIDDEN_PROJECT = {
    "defocus_cache": {"method", "scenes", "experiments", "repro"},
    "method": {"scenes", "experiments", "repro", "defocus_cache"},
    "scenes": {"method", "experiments", "repro"},
    "experiments": {"repro"},
}
#: Third-party modules method/ must not import (pure numerics: no rendering, plotting or image I/O).
FORBIDDEN_IN_METHOD = {"mitsuba", "drjit", "matplotlib", "PIL", "imageio", "tifffile", "OpenEXR", "filelock"}


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


@pytest.mark.parametrize("package", sorted(FORBIDDEN_PROJECT))
def test_layering(package):
    bad = {}
    for path in sorted((ROOT / package).rglob("*.py")):
        found = _imports(path) & FORBIDDEN_PROJECT[package]
        if package == "method":
            found |= _imports(path) & FORBIDDEN_IN_METHOD
        if found:
            bad[str(path.relative_to(ROOT))] = sorted(found)
    assert not bad, f"forbidden imports: {bad}"


def test_matplotlib_only_in_plotting_modules():
    offenders = [str(p.relative_to(ROOT)) for pkg in ("method", "scenes", "experiments")
                 for p in (ROOT / pkg).rglob("*.py")
                 if "matplotlib" in _imports(p) and "plotting" not in p.parts]
    assert not offenders, offenders


def test_photo_io_and_cache_live_where_they_say():
    """Photo files are read/written only by the photo tools (repro.estimate, repro.magnify and their map
    module repro/_photo_map.py): the package repro/photo_io/; the cache layer is its own package, defocus_cache/."""
    photo_io = ROOT / "repro" / "photo_io"
    assert (photo_io / "__init__.py").is_file() and not (ROOT / "scenes" / "photo_io.py").exists()
    assert (ROOT / "defocus_cache" / "__init__.py").is_file() and not (ROOT / "scenes" / "storage.py").exists()
    users = sorted(str(p.relative_to(ROOT)) for pkg in ("method", "scenes", "experiments", "repro", "defocus_cache")
                   for p in (ROOT / pkg).rglob("*.py") if "photo_io" in p.read_text(encoding="utf-8")
                   and photo_io not in p.parents)
    assert users == ["repro/_photo_map.py", "repro/estimate.py", "repro/magnify.py"], users


def test_the_checker_sees_imports(tmp_path):
    f = tmp_path / "m.py"
    f.write_text("import os\nfrom scenes.camera import X\nfrom . import y\ndef f():\n    import repro.cli\n")
    assert _imports(f) == {"os", "scenes", "repro"}


#: The paper's stages, one subpackage each (CONTRIBUTING.md, "Layout").
METHOD_SUBPACKAGES = ("edges", "blur", "refine", "propagation", "magnify")


def _private_imports(path: Path) -> list[str]:
    """``from <a method module> import _name`` in ``path``: another module's private name."""
    pkg = path.relative_to(ROOT).with_suffix("").parts[:-1]
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            module = (".".join(pkg[:len(pkg) - node.level + 1] + ((node.module,) if node.module else ()))
                      if node.level else node.module or "")
            found += [f"{module}.{a.name}" for a in node.names
                      if module.split(".")[0] == "method" and a.name.startswith("_") and not a.name.startswith("__")]
    return found


def test_method_modules_import_no_private_names():
    bad = {str(p.relative_to(ROOT)): _private_imports(p) for pkg in ("method", "experiments", "repro")
           for p in sorted((ROOT / pkg).rglob("*.py")) if _private_imports(p)}
    assert not bad, f"imports of another module's private names: {bad}"


def test_private_import_checker_sees_relative_and_absolute(tmp_path):
    folder = ROOT / "method" / "blur"
    probe = folder / "_probe_private_import.py"
    probe.write_text("from .model_fit import _x, y\nfrom ..edges.canny import _z\nfrom method.luma import _w\n")
    try:
        assert _private_imports(probe) == ["method.blur.model_fit._x", "method.edges.canny._z", "method.luma._w"]
    finally:
        probe.unlink()


@pytest.mark.parametrize("name", METHOD_SUBPACKAGES)
def test_method_stage_subpackages_export_public_names(name):
    import importlib

    package = importlib.import_module(f"method.{name}")
    assert package.__all__ and all(not n.startswith("_") and hasattr(package, n) for n in package.__all__)


def test_method_top_level_keeps_only_the_shared_modules():
    flat = sorted(p.name for p in (ROOT / "method").glob("*.py"))
    assert flat == ["__init__.py", "luma.py", "params.py", "pipeline.py", "presets.py", "registry.py",
                    "validation.py"], flat


#: Tuples of names in method/ that are not choices.
NOT_CHOICES = {"method.pipeline.STAGES": "the timed stages (keys of DefocusResult.timings)"}


def _name_tables(module):
    """Module-level UPPER_CASE dicts of implementations (callables, tuples of them) or descriptions, and
    tuples of strings, in ``module``: choices by name that bypass :class:`method.registry.Registry`."""
    def implementation(v):
        return callable(v) or isinstance(v, str) or (isinstance(v, tuple) and any(map(callable, v)))

    out = []
    for attr, value in vars(module).items():
        if not attr.isupper() or f"{module.__name__}.{attr}" in NOT_CHOICES:
            continue
        if isinstance(value, dict) and value and all(map(implementation, value.values())):
            out.append(attr)
        elif isinstance(value, (tuple, frozenset)) and value and all(isinstance(v, str) for v in value):
            out.append(attr)
    return out


def _method_modules():
    import importlib
    import pkgutil

    import method

    return [importlib.import_module(m.name) for m in pkgutil.walk_packages(method.__path__, "method.")]


def test_every_choice_by_name_in_method_is_a_registry():
    """One registry type: a dict of implementations or a tuple of allowed names in ``method`` fails."""
    found = {m.__name__: _name_tables(m) for m in _method_modules()}
    assert {k: v for k, v in found.items() if v} == {}


def test_the_registry_check_catches_plain_tables():
    import types

    from method.registry import Registry

    probe = types.ModuleType("probe")
    probe.SOLVERS = {"a": len}
    probe.PAIRS = {"a": (len, abs)}
    probe.NUMBERS = {"a": (1, 2)}
    probe.CHOICES = ("x", "y")
    probe.LIMITS = (1.0, 2.0)
    probe.GOOD = Registry("good", {"a": len})
    assert sorted(_name_tables(probe)) == ["CHOICES", "PAIRS", "SOLVERS"]


#: Size limits of method/ (README.md "Developers' guide"): lines per module (all lines) and lines of code
#: per function (docstring, blank and comment lines not counted).
MAX_MODULE_LINES = 500
MAX_FUNCTION_CODE_LINES = 100


def _function_code_lines(source: str) -> dict[str, int]:
    """Lines of code of every function in ``source``, {"name:lineno": count}; a nested function's
    lines count for it and for the function around it."""
    lines = source.splitlines()
    out = {}
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        first = node.body[0]
        doc = (range(first.lineno, first.end_lineno + 1) if isinstance(first, ast.Expr)
               and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str) else range(0))
        out[f"{node.name}:{node.lineno}"] = sum(
            1 for ln in range(node.lineno, node.end_lineno + 1)
            if ln not in doc and lines[ln - 1].strip() and not lines[ln - 1].strip().startswith("#"))
    return out


def _too_long_functions(source: str) -> dict[str, int]:
    """The functions of ``source`` over :data:`MAX_FUNCTION_CODE_LINES` lines of code."""
    return {k: n for k, n in _function_code_lines(source).items() if n > MAX_FUNCTION_CODE_LINES}


def test_method_modules_are_at_most_500_lines():
    long = {str(p.relative_to(ROOT)): n for p in sorted((ROOT / "method").rglob("*.py"))
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES}
    assert not long, f"modules over {MAX_MODULE_LINES} lines: {long}"


def test_scenes_experiments_and_repro_modules_are_at_most_500_lines():
    long = {str(p.relative_to(ROOT)): n for pkg in ("scenes", "experiments", "repro")
            for p in sorted((ROOT / pkg).rglob("*.py"))
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES}
    assert not long, f"modules over {MAX_MODULE_LINES} lines: {long}"


def test_method_functions_are_at_most_100_lines_of_code():
    long = {f"{p.relative_to(ROOT)}:{name}": n for p in sorted((ROOT / "method").rglob("*.py"))
            for name, n in _too_long_functions(p.read_text(encoding="utf-8")).items()}
    assert not long, f"functions over {MAX_FUNCTION_CODE_LINES} lines of code: {long}"


def test_function_length_checker_counts_code_only():
    def function(n_code, *, padding):
        body = "".join(f"    x{i} = {i}\n" for i in range(n_code - 2))  # def line and return count too
        return ('def f():\n    """Doc\n\n    lines.\n    """\n' + ("\n    # comment\n\n" * padding) + body
                + "    return 0\n")

    at_limit = function(MAX_FUNCTION_CODE_LINES, padding=50)
    assert _function_code_lines(at_limit) == {"f:1": MAX_FUNCTION_CODE_LINES}
    assert _too_long_functions(at_limit) == {}  # docstring, blank and comment lines do not count
    over = function(MAX_FUNCTION_CODE_LINES + 1, padding=0)
    assert _too_long_functions(over) == {"f:1": MAX_FUNCTION_CODE_LINES + 1}
    nested = "def outer():\n    def inner():\n        return 1\n    return inner\n"
    assert _function_code_lines(nested) == {"outer:1": 4, "inner:2": 2}


def _getattr_defaults(source: str) -> list[int]:
    """Lines of ``getattr(obj, name, default)`` calls in ``source``: a fallback that hides a missing
    attribute (and drifts from the real default) where the attribute should simply be read."""
    return sorted(node.lineno for node in ast.walk(ast.parse(source))
                  if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "getattr"
                  and (len(node.args) > 2 or node.keywords))


def test_method_reads_attributes_without_getattr_fallbacks():
    """Stage functions take their stage's parameters (or DefocusParams) and read real attributes."""
    bad = {str(p.relative_to(ROOT)): lines for p in sorted((ROOT / "method").rglob("*.py"))
           if (lines := _getattr_defaults(p.read_text(encoding="utf-8")))}
    assert not bad, f"getattr with a default in method/: {bad}"


def test_getattr_fallback_checker_sees_defaults_only():
    source = "a = getattr(p, 'x', 16)\nb = getattr(p, name)\nc = obj.getattr(p, 'y', 1)\nd = getattr(p, 'z', None)\n"
    assert _getattr_defaults(source) == [1, 4]


def _relative_imports(path: Path) -> set[str]:
    """Modules of ``method`` that ``path`` imports by a relative import (``from .x import y`` → ``x``)."""
    return {node.module or "" for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
            if isinstance(node, ast.ImportFrom) and node.level == 1}


def test_params_and_presets_do_not_import_each_other():
    """Presets are instances of DefocusParams (presets imports params); params never imports presets
    (it reads the registry presets fills), and no stage's parameters import the composition."""
    assert "params" in _relative_imports(ROOT / "method" / "presets.py")
    assert "presets" not in _relative_imports(ROOT / "method" / "params.py")
    assert "method.presets" not in _imports_full(ROOT / "method" / "params.py")
    for stage in sorted((ROOT / "method").glob("*/params.py")):
        text = stage.read_text(encoding="utf-8")
        assert "from ..params" not in text and "from ..presets" not in text and "method.params" not in \
            _imports_full(stage), stage


def _imports_full(path: Path) -> set[str]:
    """Absolute module names imported by ``path`` (``import a.b`` / ``from a.b import c`` → ``a.b``)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.add(node.module)
    return out
