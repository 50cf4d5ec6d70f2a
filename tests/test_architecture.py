"""The import rules of CONTRIBUTING.md, checked on the source (ast), so a violation fails CI.

repro may import everything; experiments imports method and scenes; method and scenes never import
each other, experiments or repro; nothing imports repro; method imports no renderer, plotting or
file-I/O library. defocus_cache (atomic writes, caches, cache keys) imports no project package and is used by
every layer but method. No two files import each other, directly or not (function-local imports count),
and no module imports another module's private (``_name``) names, in any package.
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
    """Photo files are read/written only by the photo tools (repro.estimate, repro.magnify, their map module
    repro/_photo_map.py and the magnifier's input readers repro/_magnify_inputs.py): the package repro/photo_io/;
    the cache layer is its own package, defocus_cache/."""
    photo_io = ROOT / "repro" / "photo_io"
    assert (photo_io / "__init__.py").is_file() and not (ROOT / "scenes" / "photo_io.py").exists()
    assert (ROOT / "defocus_cache" / "__init__.py").is_file() and not (ROOT / "scenes" / "storage.py").exists()
    users = sorted(str(p.relative_to(ROOT)) for pkg in ("method", "scenes", "experiments", "repro", "defocus_cache")
                   for p in (ROOT / pkg).rglob("*.py") if "photo_io" in p.read_text(encoding="utf-8")
                   and photo_io not in p.parents)
    assert users == ["repro/_magnify_inputs.py", "repro/_photo_map.py", "repro/estimate.py", "repro/magnify.py"], users


def test_the_checker_sees_imports(tmp_path):
    f = tmp_path / "m.py"
    f.write_text("import os\nfrom scenes.camera import X\nfrom . import y\ndef f():\n    import repro.cli\n")
    assert _imports(f) == {"os", "scenes", "repro"}


#: The paper's stages, one subpackage each (CONTRIBUTING.md, "Layout").
METHOD_SUBPACKAGES = ("edges", "blur", "refine", "propagation", "magnify")


#: The project's packages: every module of these is a node of the import graph.
PROJECT_PACKAGES = ("method", "scenes", "experiments", "repro", "defocus_cache")


def _modules(root: Path, packages=PROJECT_PACKAGES) -> dict[str, Path]:
    """Dotted module name → file of every ``.py`` under ``root/<package>`` (a package is its ``__init__``)."""
    out = {}
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            parts = path.relative_to(root).with_suffix("").parts
            out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


def _import_statements(name: str, path: Path):
    """``(line, module, names)`` of every import statement of module ``name`` (function-local ones too),
    relative imports resolved: ``import a.b`` → ``(n, "a.b", ())``; ``from .x import y`` →
    ``(n, "<pkg>.x", ("y",))``."""
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name, ()
        elif isinstance(node, ast.ImportFrom):
            base = package[:len(package) - node.level + 1] if node.level else []
            module = ".".join([*base, *([node.module] if node.module else [])])
            yield node.lineno, module, tuple(a.name for a in node.names)


def _owner(dotted: str, modules) -> str | None:
    """The project module ``dotted`` names, or the innermost one holding it (None: not a project module)."""
    while dotted and dotted not in modules:
        dotted = dotted.rpartition(".")[0]
    return dotted or None


def import_graph(root: Path, packages=PROJECT_PACKAGES) -> dict[str, set[str]]:
    """Module → the project modules it imports, from every import statement (function-local ones too):
    ``from p import m`` of a submodule ``m`` is an edge to ``p.m``, of a name to ``p``. The packages
    a submodule's import passes through are not edges (they are run first, but import nothing back)."""
    modules = _modules(root, packages)
    graph = {}
    for name, path in modules.items():
        targets = set()
        for _, module, names in _import_statements(name, path):
            for n in names or (None,):
                target = f"{module}.{n}" if n is not None and f"{module}.{n}" in modules else _owner(module, modules)
                if target is not None:
                    targets.add(target)
        graph[name] = targets
    return graph


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import cycles of ``graph``: its strongly connected components of more than one module, and the
    modules that import themselves (Tarjan's algorithm), each sorted."""
    index, low, stack, on_stack, cycles = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1 or v in graph.get(v, ()):
                cycles.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(cycles)


def private_imports(root: Path, packages=PROJECT_PACKAGES) -> list[str]:
    """``"file:line: from m import _name"`` for every import of another module's private name (a leading
    underscore, dunders excepted) in ``packages``. A private module (``repro/_runner.py``) may be imported;
    its private names may not."""
    modules = _modules(root, packages)
    found = []
    for name, path in modules.items():
        for line, module, names in _import_statements(name, path):
            if _owner(module, modules) is None:
                continue
            found += [f"{path.relative_to(root).as_posix()}:{line}: from {module} import {n}" for n in names
                      if n.startswith("_") and not n.startswith("__") and f"{module}.{n}" not in modules]
    return found


def test_no_import_cycles_between_files():
    """No module imports one that imports it back, directly or not, counting function-local imports
    (which hide a cycle at import time but still tie the files together)."""
    cycles = import_cycles(import_graph(ROOT))
    assert not cycles, "import cycles (break each with a leaf module): " + "; ".join(" <-> ".join(c) for c in cycles)


#: Modules that hold what several modules of their package share, so they import none of it.
LEAF_MODULES = ("experiments.cache_keys", "experiments.metric_paths", "experiments.evaluation_columns")


@pytest.mark.parametrize("name", LEAF_MODULES)
def test_shared_helpers_live_in_leaf_modules(name):
    package = name.split(".")[0]
    assert not {t for t in import_graph(ROOT)[name] if t.split(".")[0] == package}, name


def _fake_package(root: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text)
    return root


def test_cycle_checker_finds_cycles_through_local_and_relative_imports(tmp_path):
    files = {"pkg/__init__.py": "from .a import f\n", "pkg/a.py": "def f():\n    from .sub.b import g\n",
             "pkg/sub/__init__.py": "", "pkg/sub/b.py": "from ..c import h\n", "pkg/c.py": "import pkg.a\n",
             "pkg/d.py": "from pkg.d import x\n", "pkg/e.py": "import os\nfrom pkg import c\n"}
    root = _fake_package(tmp_path, files)
    graph = import_graph(root, ("pkg",))
    assert graph["pkg.a"] == {"pkg.sub.b"} and graph["pkg.sub.b"] == {"pkg.c"} and graph["pkg.e"] == {"pkg.c"}
    assert import_cycles(graph) == [["pkg.a", "pkg.c", "pkg.sub.b"], ["pkg.d"]]


def test_cycle_checker_passes_a_package_without_cycles(tmp_path):
    files = {"pkg/__init__.py": "from .a import f\n", "pkg/a.py": "def f():\n    from .sub.b import g\n",
             "pkg/sub/__init__.py": "", "pkg/sub/b.py": "from ..c import h\n", "pkg/c.py": "import numpy\nh = 1\n"}
    assert import_cycles(import_graph(_fake_package(tmp_path, files), ("pkg",))) == []


def test_no_module_imports_another_modules_private_names():
    bad = private_imports(ROOT)
    assert not bad, "imports of another module's private names (make them public or move them): " + "; ".join(bad)


def test_private_import_checker_sees_private_names_only(tmp_path):
    files = {"pkg/__init__.py": "", "pkg/_runner.py": "def run():\n    pass\n_x = 1\n",
             "pkg/sub/__init__.py": "",
             "pkg/sub/a.py": ("from .. import _runner\nfrom .._runner import run\nfrom pkg._runner import __doc__\n"
                              "from os import _exit\ndef f():\n    from ..b import _y, z\n"),
             "pkg/b.py": "from ._runner import _x\n_y = z = 2\n"}
    root = _fake_package(tmp_path, files)
    assert private_imports(root, ("pkg",)) == ["pkg/b.py:1: from pkg._runner import _x",
                                               "pkg/sub/a.py:6: from pkg.b import _y"]
    (root / "pkg/b.py").write_text("from ._runner import run\n_y = z = 2\n")
    (root / "pkg/sub/a.py").write_text("from .. import _runner\nfrom ..b import z\n")
    assert private_imports(root, ("pkg",)) == []


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
