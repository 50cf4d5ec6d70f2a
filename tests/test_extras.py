"""Optional dependencies: the core install runs ``method`` and the photo tools; the renderer and the sweep
engine are pip extras, and a missing one is one line naming it (exit 2 from a CLI, a
``ModuleNotFoundError`` naming it from the API).

Missing modules are simulated in-process (``sys.modules[name] = None``: ``import name`` then raises
``ModuleNotFoundError``) or in a subprocess with an import hook that refuses them and records who asked.
The real check, a fresh venv with ``pip install -e .`` and no extras (a warm pip cache: the packages
``make`` just installed), is a slow test: 48 s on an idle machine, about 2 min on a loaded one
(docs/extras.md).
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from repro import _cli
from repro._cli import COMMAND_EXTRAS, EXTRAS, MissingExtraError, console_main, require_extras, run_cli
from repro._cli_errors import module_installed

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
EXTRA_MODULES = sorted({m for mods in EXTRAS.values() for m in mods})


def _dist_modules(requirement: str) -> set[str]:
    """Top-level modules a requirement string installs, as far as EXTRAS can name them:
    ``"dask[distributed,diagnostics]>=2024.1"`` -> {"dask", "distributed"}."""
    m = re.match(r"\s*([A-Za-z0-9_.-]+)\s*(?:\[([^\]]*)\])?", requirement)
    name, extras = m.group(1).lower().replace("-", "_"), (m.group(2) or "")
    return {name} | {e.strip() for e in extras.split(",") if e.strip() in EXTRA_MODULES}


def _expected(command: str, extra: str, module: str) -> str:
    return f"{command} needs the '{extra}' extra ({module} is not installed): pip install -e '.[{extra}]'"


# ------------------------------------------------------------------------------------------------
# the table and pyproject agree
# ------------------------------------------------------------------------------------------------


def test_extras_table_matches_pyproject():
    optional = PYPROJECT["project"]["optional-dependencies"]
    assert set(optional) == {*EXTRAS, "all", "test"}
    for extra, modules in EXTRAS.items():
        installed = set().union(*(_dist_modules(r) for r in optional[extra]))
        assert installed == set(modules), (extra, installed)
    # 'all' is every extra of the harness (the Makefile installs '.[all,test]')
    (all_req,) = optional["all"]
    m = re.fullmatch(r"defocus-repro\[([^\]]+)\]", all_req)
    assert m and set(m.group(1).split(",")) == set(EXTRAS)
    assert "pip install -q -e '.[all,test]'" in (ROOT / "Makefile").read_text(encoding="utf-8")


def test_core_dependencies_install_no_extra_module():
    core = set().union(*(_dist_modules(r) for r in PYPROJECT["project"]["dependencies"]))
    assert not core & set(EXTRA_MODULES), core & set(EXTRA_MODULES)
    assert {"numpy", "scipy", "numba", "openexr", "matplotlib"} <= core  # what the photo tools use


def test_command_table_names_real_commands_and_extras():
    assert set(COMMAND_EXTRAS) <= {f"repro.{name}" for name in _cli.COMMANDS}
    assert all(set(extras) <= set(EXTRAS) for extras in COMMAND_EXTRAS.values())
    for free in ("repro.estimate", "repro.magnify", "repro.report", "repro.bench", "repro.evaluate"):
        assert free not in COMMAND_EXTRAS


# ------------------------------------------------------------------------------------------------
# every CLI: one line naming the extra, exit 2
# ------------------------------------------------------------------------------------------------

CASES = [  # (module, argv, missing module, command in the message, extra)
    ("repro.render", ["planes"], "mitsuba", "repro.render", "render"),
    ("repro.render", ["planes"], "drjit", "repro.render", "render"),
    ("repro.evaluate", ["--scenes", "planes"], "mitsuba", "repro.evaluate", "render"),
    ("repro.figures", [], "mitsuba", "repro.figures", "render"),
    ("repro.sweep", ["--scenes", "planes", "--fnumber", "8", "--out", "OUT"], "dask", "repro.sweep", "sweep"),
    ("repro.sweep", ["--scenes", "planes", "--fnumber", "8", "--out", "OUT"], "pyarrow", "repro.sweep", "sweep"),
    ("repro.sweep", ["--scenes", "planes", "--fnumber", "8", "--out", "OUT"], "mitsuba", "repro.sweep", "render"),
    ("repro.bench", ["--accuracy", "--out", "OUT"], "mitsuba", "repro.bench --accuracy", "render"),
    ("repro.bench", ["--sweep", "--out", "OUT"], "distributed", "repro.bench --sweep", "sweep"),
    ("repro.bench", ["--magnify", "--out", "OUT"], "mitsuba", "repro.bench --magnify", "render"),
]


@pytest.mark.parametrize("module, argv, missing, command, extra", CASES,
                         ids=[f"{c[0]}-{c[2]}" for c in CASES])
def test_cli_without_an_extra_is_one_line_naming_it_and_exit_2(module, argv, missing, command, extra,
                                                               monkeypatch, capsys, tmp_path):
    import importlib

    main = importlib.import_module(module).main
    argv = [str(tmp_path / "out") if a == "OUT" else a for a in argv]
    monkeypatch.setitem(sys.modules, missing, None)
    prog = f"python -m {module}"
    assert run_cli(main, argv, prog=prog) == 2
    out, err = capsys.readouterr()
    assert err.splitlines() == [f"{prog}: error: {_expected(command, extra, missing)}"]
    assert out == ""
    assert not (tmp_path / "out").exists()  # stopped before any work


def test_console_script_without_the_render_extra(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "mitsuba", None)
    assert console_main(["render", "planes"]) == 2
    assert capsys.readouterr().err.splitlines() == [
        f"defocus-repro render: error: {_expected('repro.render', 'render', 'mitsuba')}"]


def test_python_dash_m_without_the_sweep_extra_subprocess(tmp_path):
    """``python -m repro.sweep`` itself (the command is found from ``__main__``'s spec): no traceback."""
    code = ("import runpy, sys; sys.modules['dask'] = None; sys.argv = ['repro.sweep', '--scenes', 'planes', "
            f"'--out', {str(tmp_path / 'out')!r}]; runpy.run_module('repro.sweep', run_name='__main__', alter_sys=True)")
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.splitlines() == [f"python -m repro.sweep: error: {_expected('repro.sweep', 'sweep', 'dask')}"]


@pytest.mark.parametrize("flag", ["--help", "--version"])
def test_help_and_version_need_no_extra(flag, monkeypatch, capsys):
    from repro.render import main

    monkeypatch.setitem(sys.modules, "mitsuba", None)
    with pytest.raises(SystemExit) as exc:
        run_cli(main, [flag], prog="python -m repro.render")
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip()


def test_an_extra_module_missing_later_is_one_line_other_modules_propagate(capsys):
    def needs_parquet(argv):
        raise ModuleNotFoundError("No module named 'pyarrow.parquet'", name="pyarrow.parquet")

    def needs_nothing_known(argv):
        raise ModuleNotFoundError("No module named 'not_a_project_dependency'", name="not_a_project_dependency")

    assert run_cli(needs_parquet, [], prog="tool") == 2
    assert capsys.readouterr().err.splitlines() == [f"tool: error: {_expected(__name__, 'sweep', 'pyarrow')}"]
    with pytest.raises(ModuleNotFoundError):  # not an extra's: a bug, with its traceback
        run_cli(needs_nothing_known, [], prog="tool")


def test_require_extras_both_sides(monkeypatch):
    for extra, modules in EXTRAS.items():
        if all(module_installed(m) for m in modules):
            require_extras(extra, command="x")  # installed: no error
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    with pytest.raises(MissingExtraError, match=r"^x needs the 'sweep' extra \(pyarrow is not installed\)"):
        require_extras("sweep", command="x")
    with pytest.raises(ValueError, match="unknown extra 'gpu'; allowed: render, sweep"):
        require_extras("gpu", command="x")


# ------------------------------------------------------------------------------------------------
# the API: scenes.backend.require_mitsuba
# ------------------------------------------------------------------------------------------------


def test_require_mitsuba_names_the_render_extra(monkeypatch):
    from scenes.backend import require_mitsuba

    if module_installed("mitsuba") and module_installed("drjit"):
        require_mitsuba()  # installed: no error
    for missing in ("mitsuba", "drjit"):
        with monkeypatch.context() as m:
            m.setitem(sys.modules, missing, None)
            with pytest.raises(ModuleNotFoundError) as exc:
                require_mitsuba()
        assert exc.value.name == missing
        assert str(exc.value) == (f"rendering needs the 'render' extra ({missing} is not installed): "
                                  "pip install -e '.[render]'")


def test_render_scene_without_mitsuba_names_the_extra_subprocess(tmp_path):
    """A fresh process (select_variant's cache empty): the first render call raises the named error."""
    code = ("import sys; sys.modules['mitsuba'] = None\n"
            "from scenes import render_scene\n"
            "try:\n    render_scene('planes', progress=False)\n"
            "except ModuleNotFoundError as e:\n    print(e.name, '|', e)\n")
    env = {**os.environ, "DEFOCUS_CACHE_DIR": str(tmp_path / "cache")}
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, env=env,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == ("mitsuba | rendering needs the 'render' extra (mitsuba is not installed): "
                                   "pip install -e '.[render]'")


# ------------------------------------------------------------------------------------------------
# the photo tools never import an extra's module
# ------------------------------------------------------------------------------------------------

_REFUSE = r"""
import importlib.abc, json, os, sys, traceback
REFUSED, ASKED = set(sys.argv[1].split(',')), []
class Refuse(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name.split('.')[0] in REFUSED:
            caller = next((f.filename for f in reversed(traceback.extract_stack())
                           if not f.filename.startswith('<') and f.filename != __file__), '?')
            ASKED.append([name, caller])
            raise ModuleNotFoundError(f'No module named {name!r}', name=name)
sys.meta_path.insert(0, Refuse())
from repro._cli import run_cli
import method, scenes, experiments, defocus_cache, repro.photo_io
from repro import estimate, magnify
photo, out = sys.argv[2], sys.argv[3]
s1 = run_cli(estimate.main, [photo, '-o', out + '/map.exr', '-q'], prog='estimate')
s2 = run_cli(magnify.main, [photo, '-o', out + '/mag.png', '--save-map', out + '/map.png', '-q'], prog='magnify')
print(json.dumps({'status': [s1, s2], 'asked': ASKED}))
"""


def test_photo_tools_run_and_the_project_imports_no_extra_module(tmp_path):
    from skimage import data, transform

    from repro.photo_io import write_photo

    image = transform.resize(data.astronaut()[100:356, 130:386], (128, 128), anti_aliasing=True)
    photo = write_photo(tmp_path / "photo.png", image)
    env = {**os.environ, "DEFOCUS_CACHE_DIR": str(tmp_path / "cache")}
    script = tmp_path / "refuse.py"
    script.write_text(_REFUSE)
    proc = subprocess.run([sys.executable, str(script), ",".join(EXTRA_MODULES), str(photo), str(tmp_path)],
                          cwd=tmp_path, capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    assert result["status"] == [0, 0], proc.stderr
    project = [(name, f) for name, f in result["asked"] if str(ROOT) in f and "site-packages" not in f]
    assert project == [], project  # no project module asked for mitsuba, drjit, dask, distributed, pyarrow
    for name in ("map.exr", "mag.png", "map.png"):
        assert (tmp_path / name).stat().st_size > 0


_REFUSE_MAPS = _REFUSE.split("from repro import estimate, magnify")[0] + r"""
from repro import evaluate
data, maps, out = sys.argv[2], sys.argv[3], sys.argv[4]
s = run_cli(evaluate.main, ['--maps', maps, '--dataset', data, '--protocol', 'harness', 'rtf', 'syndof',
                            'detection', '--out', out, '-q'], prog='evaluate')
print(json.dumps({'status': [s], 'asked': ASKED}))
"""


def test_evaluate_maps_with_a_dataset_imports_no_extra_module(tmp_path):
    """``repro.evaluate --maps --dataset`` runs with mitsuba, drjit, dask, distributed and pyarrow refused."""
    import numpy as np

    from tests.test_external_maps import _gt, make_dataset

    data = make_dataset(tmp_path / "data", {"planes_f8_small": _gt(np.ones((4, 5)))})
    (tmp_path / "maps").mkdir()
    np.save(tmp_path / "maps" / "planes_f8_small.npy", np.full((4, 5), 1.5))
    script = tmp_path / "refuse.py"
    script.write_text(_REFUSE_MAPS)
    env = {**os.environ, "DEFOCUS_CACHE_DIR": str(tmp_path / "cache"),
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, str(script), ",".join(EXTRA_MODULES), str(data), str(tmp_path / "maps"),
                           str(tmp_path / "out")], cwd=tmp_path, capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    assert result["status"] == [0], proc.stderr
    project = [(name, f) for name, f in result["asked"] if str(ROOT) in f and "site-packages" not in f]
    assert project == [], project
    rows = json.loads((tmp_path / "out" / "maps.json").read_text())["rows"]
    assert {r["protocol"] for r in rows} == {"harness", "rtf", "syndof", "detection"}


def test_evaluate_maps_without_a_dataset_needs_the_render_extra(monkeypatch, capsys, tmp_path):
    from repro.evaluate import main

    (tmp_path / "maps").mkdir()
    monkeypatch.setitem(sys.modules, "mitsuba", None)
    prog = "python -m repro.evaluate"
    assert run_cli(main, ["--maps", str(tmp_path / "maps")], prog=prog) == 2
    assert capsys.readouterr().err.splitlines() == [
        f"{prog}: error: {_expected('repro.evaluate --maps without --dataset', 'render', 'mitsuba')}"]


# ------------------------------------------------------------------------------------------------
# the real check: a venv with the core install only (slow)
# ------------------------------------------------------------------------------------------------


@pytest.mark.slow
def test_core_install_in_a_fresh_venv_estimates_and_names_the_extras(tmp_path):
    from skimage import data

    from repro.photo_io import write_photo

    venv = tmp_path / "venv"
    # No pip of its own (ensurepip: 6 CPU-s): this environment's pip installs into
    # it and lists it (``pip --python``).
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True, timeout=300)
    py = venv / "bin" / "python"
    pip = [sys.executable, "-m", "pip", "--python", str(py)]
    subprocess.run([*pip, "install", "-q", "-e", str(ROOT)], check=True, timeout=1200, cwd=tmp_path,
                   capture_output=True)
    listed = subprocess.run([*pip, "list", "--format", "json"], check=True, capture_output=True, text=True).stdout
    names = {d["name"].lower() for d in json.loads(listed)}
    assert not names & {"mitsuba", "drjit", "dask", "distributed", "pyarrow"}, names
    photo = write_photo(tmp_path / "photo.png", data.astronaut()[::4, ::4] / 255.0)
    env = {**os.environ, "DEFOCUS_CACHE_DIR": str(tmp_path / "cache")}
    env.pop("PYTHONPATH", None)
    est = subprocess.run([str(py), "-m", "repro.estimate", str(photo)], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=900)
    assert est.returncode == 0, est.stderr
    assert (tmp_path / "photo.defocus.exr").stat().st_size > 0
    for module, argv, command, extra, missing in [("repro.render", ["planes"], "repro.render", "render", "mitsuba"),
                                                  ("repro.sweep", ["--scenes", "planes", "--out", "o"],
                                                   "repro.sweep", "sweep", "dask")]:
        proc = subprocess.run([str(py), "-m", module, *argv], cwd=tmp_path, env=env, capture_output=True,
                              text=True, timeout=300)
        assert proc.returncode == 2
        assert proc.stderr.splitlines() == [f"python -m {module}: error: {_expected(command, extra, missing)}"]
