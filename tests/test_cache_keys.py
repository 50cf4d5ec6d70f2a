"""Cache keys: library versions, scene content and source fingerprints; where caches live."""

import dataclasses
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import defocus_cache
from defocus_cache import KEY_LIBRARIES, default_cache_root, hash_key, library_versions, source_fingerprint

ROOT = Path(__file__).resolve().parents[1]


def test_key_libraries_cover_numerics_and_rendering():
    for pkg in ("numpy", "scipy", "scikit-image", "pyamg", "numba", "mitsuba", "drjit", "pymatting",
                "colour-science", "Pillow", "OpenEXR", "tifffile", "imagecodecs"):
        assert pkg in KEY_LIBRARIES
    v = library_versions()
    import numpy

    assert v["numpy"] == numpy.__version__ and set(KEY_LIBRARIES) <= set(v)
    assert library_versions(("no-such-distribution-xyz",))["no-such-distribution-xyz"] is None


def test_source_fingerprint_follows_file_content(tmp_path):
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "a.py").write_text("X = 1\n")
    (pkg / "plot.py").write_text("Y = 1\n")
    first = source_fingerprint(pkg)
    assert source_fingerprint(pkg) == first
    (pkg / "a.py").write_text("X = 2\n")
    second = source_fingerprint(pkg)
    assert second != first
    # an excluded path does not count
    rel = (pkg / "plot.py").resolve().as_posix()
    excl = source_fingerprint(pkg, exclude=(rel,))
    (pkg / "plot.py").write_text("Y = 2\n")
    assert source_fingerprint(pkg, exclude=(rel,)) == excl
    assert source_fingerprint(pkg) != second


def test_source_fingerprint_ignores_docstrings_and_comments(tmp_path):
    """A docstring or comment edit keeps the fingerprint; a one-token code change does not."""
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    src = '"""Module doc."""\n\ndef f(x):\n    """Doc."""\n    return x + 1  # note\n\nclass C:\n    "doc"\n    y = 2\n'
    (pkg / "a.py").write_text(src)
    first = source_fingerprint(pkg)
    (pkg / "a.py").write_text(src.replace("Module doc.", "Edited.").replace("# note", "# other note")
                              .replace('"""Doc."""', '"""A longer\n    docstring."""').replace('"doc"', "'x'"))
    assert source_fingerprint(pkg) == first
    (pkg / "a.py").write_text(src.replace("x + 1", "x + 2"))
    assert source_fingerprint(pkg) != first
    (pkg / "a.py").write_text(src.replace("y = 2", "y = '2'"))
    assert source_fingerprint(pkg) != first


def test_cache_entry_survives_a_docstring_edit(tmp_path):
    """A cache entry keyed by the fingerprint of a module is found again after its docstring changes."""
    from defocus_cache import Cache

    mod = tmp_path / "m.py"
    mod.write_text('def k():\n    """v1"""\n    return 1\n')
    cache = Cache(tmp_path / "cache")
    calls = []

    def build(folder):
        calls.append(1)
        (folder / "x.txt").write_text("x")

    cache.get_or_build({"code": source_fingerprint(mod)}, build)
    mod.write_text('def k():\n    """v2, reworded"""\n    return 1  # comment\n')
    cache.get_or_build({"code": source_fingerprint(mod)}, build)
    assert len(calls) == 1
    mod.write_text('def k():\n    """v2, reworded"""\n    return 2\n')
    cache.get_or_build({"code": source_fingerprint(mod)}, build)
    assert len(calls) == 2


def test_source_fingerprint_of_functions():
    def f(x):
        return x + 1

    def g(x):
        return x + 2

    assert source_fingerprint(f) == source_fingerprint(f)
    assert source_fingerprint(f) != source_fingerprint(g)


def test_code_fingerprints_are_one_function():
    """The figure, photo-map and estimator fingerprints all come from defocus_cache.source_fingerprint."""
    import experiments
    import method
    import scenes
    from experiments.evaluation import estimator_fingerprint
    from experiments.cache_keys import FINGERPRINT_EXCLUDED, code_fingerprint
    from method import BLUR_ESTIMATORS

    assert code_fingerprint() == source_fingerprint(method, scenes, experiments, exclude=FINGERPRINT_EXCLUDED)
    assert estimator_fingerprint("model_fit") == source_fingerprint(BLUR_ESTIMATORS["model_fit"])
    for path in ("repro/estimate.py", "experiments/registry.py", "experiments/cache_keys.py", "experiments/evaluation.py"):
        text = (ROOT / path).read_text()
        assert "hashlib" not in text and "getsource" not in text, path


def _version_changed(monkeypatch, pkg):
    real = library_versions()
    fake = {**real, pkg: "0.0.0-test"}
    monkeypatch.setattr(defocus_cache, "library_versions", lambda *a, **k: fake)
    return real, fake


@pytest.mark.parametrize("pkg", ["numpy", "scikit-image", "pyamg", "numba", "drjit", "pymatting"])
def test_figure_key_changes_with_library_version(monkeypatch, pkg):
    from experiments.cache_keys import cache_key
    from experiments.registry import FIGURES

    fig = FIGURES["fig10"]
    cfg = fig.configs["quick"] if isinstance(fig.configs, dict) and "quick" in fig.configs else next(iter(fig.configs.values()))
    before = hash_key(cache_key(fig, cfg))
    assert hash_key(cache_key(fig, cfg)) == before  # same inputs, same key
    _version_changed(monkeypatch, pkg)
    assert hash_key(cache_key(fig, cfg)) != before


def _camera():
    from scenes.library import SCENES

    return SCENES["tilted_plane"].camera("small")


def test_render_key_changes_with_versions_and_content():
    from scenes.library import SCENES
    from scenes.render import render_key

    sdef = SCENES["tilted_plane"]
    libs = library_versions()
    kw = dict(spp=16, seed=0, variant="scalar_rgb", sigma_convention="line_spread")
    base = hash_key(render_key(sdef, _camera(), scene_content="abc", libraries=libs, **kw))
    assert hash_key(render_key(sdef, _camera(), scene_content="abc", libraries=libs, **kw)) == base
    for pkg in ("mitsuba", "drjit", "numpy", "scipy"):
        other = {**libs, pkg: "0.0.0-test"}
        assert hash_key(render_key(sdef, _camera(), scene_content="abc", libraries=other, **kw)) != base, pkg
    assert hash_key(render_key(sdef, _camera(), scene_content="abd", libraries=libs, **kw)) != base
    # a hand-bumped version number is not part of the key
    bumped = dataclasses.replace(sdef, version=sdef.version + 1)
    assert hash_key(render_key(bumped, _camera(), scene_content="abc", libraries=libs, **kw)) == base


@pytest.mark.render
def test_scene_content_hash_follows_scene_parameters():
    from scenes.backend import import_mitsuba
    from scenes.library import SCENES
    from scenes.library.base import emissive, facing_rectangle, image_extent
    from scenes.render import scene_content_hash

    _mi, variant = import_mitsuba(None)
    sdef = SCENES["tilted_plane"]
    h = scene_content_hash(sdef, variant=variant)
    assert len(h) == 16 and scene_content_hash(sdef, variant=variant) == h

    import numpy as np

    def make(z, value):
        def shapes():
            ext = image_extent(1.0)
            return {"plane": emissive(facing_rectangle(z, -1, 1, -1, 1, extent=ext), np.full((4, 4, 3), value))}
        return dataclasses.replace(sdef, name="test_plane", shapes=shapes)

    a = scene_content_hash(make(1.0, 0.5), variant=variant)
    assert scene_content_hash(make(1.0, 0.5), variant=variant) == a
    assert scene_content_hash(make(1.5, 0.5), variant=variant) != a   # geometry
    assert scene_content_hash(make(1.0, 0.25), variant=variant) != a  # texture
    lit = dataclasses.replace(make(1.0, 0.5), integrator={"type": "path", "max_depth": 3})
    assert scene_content_hash(lit, variant=variant) != a               # lighting / integrator


def test_scene_content_hash_is_stable_across_processes(tmp_path):
    """Same scene, fresh processes (one computes, one reads the memo, one recomputes): one hash."""
    code = textwrap.dedent("""
        from scenes.backend import import_mitsuba
        from scenes.library import SCENES
        from scenes.render import scene_content_hash
        _mi, v = import_mitsuba("scalar_rgb")
        print(scene_content_hash(SCENES["tilted_plane"], variant=v))
    """)
    env = {**os.environ, "DEFOCUS_CACHE_DIR": str(tmp_path / "c1"), "DEFOCUS_MITSUBA_VARIANT": "scalar_rgb"}
    run = lambda e: subprocess.run([sys.executable, "-c", code], env=e, cwd=ROOT, capture_output=True,
                                   text=True, check=True).stdout.strip()
    first, memo = run(env), run(env)
    fresh = run({**env, "DEFOCUS_CACHE_DIR": str(tmp_path / "c2")})
    assert first == memo == fresh and len(first) == 16
    assert list((tmp_path / "c1" / "scene_hashes").glob("*.json"))


def test_cache_root_in_source_checkout_and_installed(tmp_path, monkeypatch):
    monkeypatch.delenv(defocus_cache.CACHE_ENV, raising=False)
    # this checkout
    assert default_cache_root() == ROOT / ".cache"
    checkout = tmp_path / "src"
    checkout.mkdir()
    (checkout / "pyproject.toml").write_text("[project]\nname='x'\n")
    assert default_cache_root(project_root=checkout) == checkout / ".cache"
    # a normal install: packages in site-packages (no pyproject there) -> the user cache folder
    import platformdirs

    site = tmp_path / "venv" / "lib" / "python3.11" / "site-packages"
    site.mkdir(parents=True)
    got = default_cache_root(project_root=site)
    assert got == Path(platformdirs.user_cache_dir("defocus-repro", appauthor=False))
    assert "site-packages" not in got.parts
    (site / "pyproject.toml").write_text("")  # even a stray pyproject in site-packages is not a checkout
    assert "site-packages" not in default_cache_root(project_root=site).parts
    monkeypatch.setenv(defocus_cache.CACHE_ENV, str(tmp_path / "mine"))
    assert default_cache_root(project_root=site) == tmp_path / "mine"


def test_cache_root_of_an_installed_copy(tmp_path):
    """The packages copied into a site-packages folder and imported from there: caches go to the user
    cache dir, not next to the code."""
    import shutil

    site = tmp_path / "site-packages"
    shutil.copytree(ROOT / "defocus_cache", site / "defocus_cache", ignore=shutil.ignore_patterns("__pycache__"))
    env = {k: v for k, v in os.environ.items() if k != defocus_cache.CACHE_ENV}
    env["PYTHONPATH"] = str(site)
    env["XDG_CACHE_HOME"] = str(tmp_path / "xdg")
    out = subprocess.run([sys.executable, "-c", "import defocus_cache as s; print(s.__file__); print(s.default_cache_root())"],
                         env=env, cwd=tmp_path, capture_output=True, text=True, check=True).stdout.split("\n")
    assert out[0].startswith(str(site))
    assert Path(out[1]) == tmp_path / "xdg" / "defocus-repro"


@pytest.mark.render
def test_render_force_rebuilds_the_entry(tmp_path, monkeypatch):
    monkeypatch.setenv(defocus_cache.CACHE_ENV, str(tmp_path / "cache"))
    from scenes.library import SCENES
    from scenes.render import render_scene

    sdef = SCENES["tilted_plane"]
    cam = sdef.camera("small", resolution=(32, 24))
    first = render_scene(sdef, cam, spp=4, progress=False)
    manifest = first.path.parent / "manifest.json"
    stamp = manifest.stat().st_mtime_ns
    again = render_scene(sdef, cam, spp=4, progress=False)
    assert again.path == first.path and manifest.stat().st_mtime_ns == stamp  # reused
    forced = render_scene(sdef, cam, spp=4, progress=False, force=True)
    assert forced.path == first.path and manifest.stat().st_mtime_ns != stamp  # rebuilt in place
    import numpy as np

    np.testing.assert_array_equal(forced.rgb, first.rgb)  # same key, same pixels


# --- fingerprints of meaning: docstrings, comments and layout do not count; code does ------------------

def _docstring_edit(text: str) -> str:
    """Edit every kind of non-code text of a module: its docstring, a function docstring, comments, blank lines."""
    import ast

    tree = ast.parse(text)
    func = next(n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef) and ast.get_docstring(n))
    doc = func.body[0].value
    lines = text.splitlines(keepends=True)
    # a docstring's first line gets more words, a comment line and a blank line are added after it
    i = doc.lineno - 1
    lines[i] = lines[i].replace('"""', '"""Edited, and longer. ', 1)
    lines.insert(doc.end_lineno, "    # a new comment about nothing\n\n")
    out = "".join(lines)
    return out.replace('"""', '"""Module docstring edited. ', 1)


def _one_token_change(text: str) -> str:
    """Change one token of code: the first ``return <name>`` becomes ``return -<name>`` (a unary minus)."""
    import io
    import tokenize

    toks = list(tokenize.generate_tokens(io.StringIO(text).readline))
    i = next(i for i, (t, n) in enumerate(zip(toks, toks[1:]))
             if t.type == tokenize.NAME and t.string == "return" and n.type == tokenize.NAME)
    row, col = toks[i + 1].start
    lines = text.splitlines(keepends=True)
    lines[row - 1] = lines[row - 1][:col] + "-" + lines[row - 1][col:]
    return "".join(lines)


def test_docstring_edit_keeps_cache_entry_code_change_invalidates(tmp_path):
    """A cache keyed by source_fingerprint of a copy of a real module (method/blur/estimators.py): the entry
    built before a docstring/comment edit is served after it; a one-token code change misses it."""
    from defocus_cache import Cache

    pkg = tmp_path / "pkg"
    pkg.mkdir()
    src = (ROOT / "method" / "blur" / "estimators.py").read_text()
    (pkg / "mod.py").write_text(src)
    cache = Cache(tmp_path / "cache")
    builds = []

    def build(folder):
        builds.append(1)
        (folder / "out.txt").write_text("built")

    def key():
        return {"code": source_fingerprint(pkg), "libraries": library_versions()}

    cache.get_or_build(key(), build)
    assert len(builds) == 1
    edited = _docstring_edit(src)
    assert edited != src and edited.count("#") > src.count("#")
    (pkg / "mod.py").write_text(edited)
    assert cache.is_valid(key())
    cache.get_or_build(key(), build)
    assert len(builds) == 1  # served, not rebuilt
    (pkg / "mod.py").write_text(_one_token_change(edited))
    assert not cache.is_valid(key())
    cache.get_or_build(key(), build)
    assert len(builds) == 2
    # and back: the original code's entry is still there
    (pkg / "mod.py").write_text(src)
    assert cache.is_valid(key())


def test_function_fingerprint_ignores_docstring_and_comments(tmp_path):
    """A callable's fingerprint (its qualified name + the meaning of its source) keeps through a
    docstring/comment edit of the function and changes with one token of its code."""
    import importlib.util

    versions = {
        "base": 'def f(x):\n    """Add one."""\n    return x + 1  # one\n',
        "doc": 'def f(x):\n    # a comment\n    """Add one to x (re-worded)."""\n\n    return x + 1\n',
        "code": 'def f(x):\n    """Add one."""\n    return x - 1  # one\n',
    }
    fps = {}
    for name, text in versions.items():
        path = tmp_path / name / "fpmod.py"
        path.parent.mkdir()
        path.write_text(text)
        spec = importlib.util.spec_from_file_location("fpmod", path)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        fps[name] = source_fingerprint(mod.f)
    assert fps["base"] == fps["doc"]
    assert fps["base"] != fps["code"]


def test_fingerprint_of_project_packages_ignores_docstrings(tmp_path):
    """Every module of method/ and experiments/: stripping all its docstrings and comments keeps its
    fingerprint (so the project's caches key on code only)."""
    import ast
    import io
    import tokenize

    for name in ("method", "experiments"):
        for path in sorted((ROOT / name).rglob("*.py"))[:40]:
            text = path.read_text()
            toks = [t for t in tokenize.generate_tokens(io.StringIO(text).readline) if t.type != tokenize.COMMENT]
            no_comments = tokenize.untokenize(toks)
            a, b = tmp_path / "a.py", tmp_path / "b.py"
            a.write_text(text)
            b.write_text(no_comments)
            from defocus_cache import _code_meaning

            assert _code_meaning(a.read_text()) == _code_meaning(b.read_text()), path
            assert ast.dump(ast.parse(text)) == ast.dump(ast.parse(no_comments))


#: Third-party modules imported by method/ and scenes/ that cannot change a number (progress bars, locks,
#: thread limits: the numbers are computed single-threaded where it matters).
NUMBER_NEUTRAL = {"threadpoolctl", "tqdm", "filelock"}


def test_key_libraries_hold_every_library_method_and_scenes_import():
    """Every third-party distribution imported anywhere in method/ or scenes/ (at any depth, function-local
    imports included) is in the cache key, unless it is listed as unable to change a number."""
    import ast
    from importlib.metadata import packages_distributions

    dists = {**packages_distributions(), "OpenEXR": ["OpenEXR"]}  # a compiled module the metadata does not list
    top = set()
    for pkg in ("method", "scenes"):
        for path in (ROOT / pkg).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.Import):
                    top.update(a.name.split(".")[0] for a in node.names)
                elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                    top.add(node.module.split(".")[0])
    third_party = {m for m in top if m in dists and m not in ("method", "scenes", "defocus_cache")}
    assert {"colour", "PIL", "OpenEXR", "numpy"} <= third_party  # the scan sees function-local imports
    keyed = {d.lower() for d in KEY_LIBRARIES}
    missing = sorted(m for m in third_party - NUMBER_NEUTRAL if not any(d.lower() in keyed for d in dists[m]))
    assert missing == []
