"""The README's "Adding a blur estimator" recipe, run as written: the module and the pyproject.toml of its
code blocks written to a package in a temporary folder, installed with pip (``pip install -e``) into a
temporary venv, and the recipe's ``--procedural`` command run on two small procedural scenes on two Dask
workers, which find the estimator through its entry point (by import path; the registry is never pickled).

The venv is made cheap: ``python -m venv --without-pip`` on top of this Python, with a ``.pth`` file that
adds this environment's site-packages (so nothing is installed but the tiny package, and this
environment is not touched). The build backend (setuptools, as the recipe's pyproject says) comes from pip's
configured index through build isolation; without one the test is skipped, naming why.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

pytest.importorskip("distributed")  # the 'sweep' extra

ROOT = Path(__file__).resolve().parents[1]
SECTION = "## Adding a blur estimator"
#: Seconds for pip (a build backend fetched from the index) and for the evaluation (renders cached: ≈ 40 s).
PIP_TIMEOUT_S = 300
RUN_TIMEOUT_S = 900


def _recipe() -> dict:
    """The recipe's blocks: ``module`` (file name, text), ``pyproject`` text and the ``--procedural`` command."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text[text.index(SECTION):]
    section = section[:section.index("\n## ", len(SECTION))]
    blocks = re.findall(r"```(\w+)\n(.*?)```", section, flags=re.S)
    python = [b for lang, b in blocks if lang == "python"]
    toml = [b for lang, b in blocks if lang == "toml"]
    shell = [line.split("#")[0].strip() for lang, b in blocks if lang == "sh" for line in b.splitlines()]
    assert len(python) == 1 and len(toml) == 1, "the recipe has one python and one toml block"
    name = re.match(r"#\s*(\S+\.py)", python[0]).group(1)
    procedural = [c for c in shell if "--procedural" in c]
    assert len(procedural) == 1 and procedural[0].startswith("python -m repro.evaluate "), shell
    assert "pip install -e ." in section
    return {"module": (name, python[0]), "pyproject": toml[0], "procedural": procedural[0].split()}


def _entry_point(pyproject: str) -> tuple[str, str]:
    """(name, module:function) of the recipe's ``defocus_repro.estimators`` entry point."""
    m = re.search(r'\[project\.entry-points\."defocus_repro\.estimators"\]\s*\n(\w+)\s*=\s*"([^"]+)"', pyproject)
    assert m, pyproject
    return m.group(1), m.group(2)


def _venv(tmp_path: Path) -> Path:
    """A venv whose Python also sees this environment's packages (a .pth file), without pip of its own."""
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True, timeout=120)
    python = venv / "bin" / "python"
    site = subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                          check=True, capture_output=True, text=True).stdout.strip()
    Path(site, "_parent_environment.pth").write_text(
        f"import site; site.addsitedir({sysconfig.get_paths()['purelib']!r})\n")
    return python


@pytest.mark.slow
@pytest.mark.render
def test_readme_recipe_installed_with_pip_is_scored_on_dask_workers(tmp_path):
    recipe = _recipe()
    name, target = _entry_point(recipe["pyproject"])
    pkg = tmp_path / "my-package"
    pkg.mkdir()
    module_file, module_text = recipe["module"]
    (pkg / module_file).write_text(module_text)
    (pkg / "pyproject.toml").write_text(recipe["pyproject"])
    python = _venv(tmp_path)
    env = {**os.environ, "PYTHONPATH": str(ROOT), "TMPDIR": str(tmp_path)}
    pip = subprocess.run([str(python), "-m", "pip", "install", "-q", "--no-deps", "-e", "."], cwd=pkg, env=env,
                         capture_output=True, text=True, timeout=PIP_TIMEOUT_S)
    if pip.returncode != 0 and "No matching distribution found for setuptools" in pip.stderr:
        pytest.skip("pip has no index to fetch the recipe's build backend (setuptools) from")
    assert pip.returncode == 0, pip.stderr
    # installed into the temporary venv only
    where = subprocess.run([str(python), "-c", "import sys, importlib.metadata as m; "
                            "print(sys.prefix); print(m.distribution('my-blur').locate_file(''))"],
                           env=env, capture_output=True, text=True, check=True).stdout.split()
    assert Path(where[0]) == tmp_path / "venv" and str(tmp_path / "venv") in where[1], where
    # the recipe's command, two small dev scenes on two Dask workers, f/8 only (the machine is small)
    argv = recipe["procedural"][3:]
    argv[argv.index("--procedural") + 1] = "2"
    assert name in argv and "--split" in argv
    out = tmp_path / "evaluations"
    run = subprocess.run([str(python), "-m", "repro.evaluate", *argv, "--scene-size", "small", "--workers", "2",
                          "--fnumber", "8", "--out", str(out), "-q"], cwd=tmp_path, env=env, capture_output=True,
                         text=True, timeout=RUN_TIMEOUT_S)
    assert run.returncode == 0, run.stderr[-4000:]
    assert "engine: LocalCluster with 2 worker(s)" in run.stderr, run.stderr
    import csv

    (table,) = out.glob("*/results.csv")
    with table.open() as f:
        rows = [r for r in csv.DictReader(f) if r["metric"] == "dense_textured_mae"]
    got = {(r["preset"], r["estimator"], r["seed"]) for r in rows}
    baselines = {(b, "", s) for b in ("const_median_gt", "const_floor") for s in ("0", "1")}  # scored beside them
    assert got == {("paper", est, s) for est in ("model_fit", name) for s in ("0", "1")} | baselines, got
    assert all(r["value"] not in ("", "nan") for r in rows), rows
    failed = [r for r in csv.DictReader(table.open()) if r["metric"] == "pipeline_failed" and float(r["value"]) != 0]
    assert not failed, failed
    # the workers ran it from the installed package: the recipe's function, not a copy of it
    assert target.split(":")[1] in module_text
