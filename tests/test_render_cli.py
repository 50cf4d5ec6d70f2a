"""python -m repro.render: --list, a render (subprocesses: the real entry point), and every bad input → one
stderr line, exit 2, nothing written (in process, tests/cli_run.py)."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from scenes.library import SCENES

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli-cache")
    proj = Path(os.environ.get("DEFOCUS_CACHE_DIR") or ROOT / ".cache")
    if (proj / "variant-probes.json").exists():
        (d / "variant-probes.json").write_bytes((proj / "variant-probes.json").read_bytes())
    e = dict(os.environ, DEFOCUS_CACHE_DIR=str(d))
    e.pop("DEFOCUS_MITSUBA_VARIANT", None)
    return e


def run(args, env):
    return subprocess.run([sys.executable, "-m", "repro.render", *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=300)


def run_here(args, env):
    """The same command in this process (tests/cli_run.py): the bad-input cases need no new interpreter."""
    from tests.cli_run import run_in_process

    return run_in_process("repro.render", args, env=env)


def _renders(env):
    d = Path(env["DEFOCUS_CACHE_DIR"]) / "renders"
    return sorted(p.name for p in d.iterdir()) if d.exists() else []


#: The scene whose σ_gt ranges ``test_list`` measures (one ray cast per preset); the others' are stubbed.
MEASURED = "planes"


@pytest.mark.render
def test_list(monkeypatch):
    """--list: each scene's set, camera and σ_gt range per preset and f-number, printed from
    scenes.library.ranges.sigma_gt_ranges (in process: every scene but one gets stub ranges, whose numbers
    must be the ones printed; :data:`MEASURED`'s are measured on its ground truth and equal a second call's)."""
    import re

    from scenes.camera import CAMERA_PRESETS
    from scenes.library import SCENE_SETS, ranges

    real = ranges.sigma_gt_ranges
    called = []

    def stub_or_real(sdef, *, variant=None, **kw):
        called.append((sdef.name, variant))
        if sdef.name == MEASURED:
            return real(sdef, variant=variant, **kw)
        k = sorted(SCENES).index(sdef.name)  # numbers of each scene's own
        return {p: {"depth_m": [1.0, 2.0], "f_numbers": {f"{n:g}": {"min_px": k + 0.25 * j, "max_px": k + 10.5 + j,
                                                                   "p95_px": k + 9.0}
                                                         for j, n in enumerate((8.0, 4.0))}}
                for p in ("small", "full")}

    monkeypatch.setattr(ranges, "sigma_gt_ranges", stub_or_real)
    monkeypatch.delenv("DEFOCUS_MITSUBA_VARIANT", raising=False)
    p = run_here(["--list", "--quiet"], None)
    assert p.returncode == 0, p.stderr
    assert called == [(name, None) for name in SCENES]
    lines = p.stdout.strip().splitlines()
    assert len(lines) == 4 * len(SCENES) + 1 and "measured from each scene's ground truth" in lines[-1]
    for i, name in enumerate(SCENES):
        head, cam, small, full = lines[4 * i: 4 * i + 4]
        sset = next(k for k, v in SCENE_SETS.items() if name in v)
        assert head.startswith(f"{name}  [{sset}]") and SCENES[name].description in head
        lens = CAMERA_PRESETS[SCENES[name].camera_name]
        assert SCENES[name].camera_name in cam and f"f = {lens.focal_length_mm:g} mm" in cam
        want_ranges = real(name) if name == MEASURED else stub_or_real(SCENES[name])
        for preset, line in (("small", small), ("full", full)):
            got = {float(n): (float(a), float(b)) for n, a, b in re.findall(r"f/(\d+) ([\d.]+)-([\d.]+) px", line)}
            assert set(got) == {8.0, 4.0}, line
            for n, (lo, hi) in got.items():
                want = want_ranges[preset]["f_numbers"][f"{n:g}"]
                assert (lo, hi) == (round(want["min_px"], 2), round(want["max_px"], 2)), (name, line)


@pytest.mark.render
def test_render_to_out(env, tmp_path):
    out = tmp_path / "planes.exr"
    p = run(["planes", "--preset", "small", "--spp", "16", "--fnumber", "4", "-o", str(out), "--quiet"], env)
    assert p.returncode == 0, p.stderr
    assert out.is_file() and out.with_suffix(".json").is_file()
    assert str(out) in p.stdout and "sigma_gt" in p.stdout
    from scenes.render import load_render

    r = load_render(out)
    assert r.metadata["spp"] == 16 and r.camera.f_number == 4.0 and r.rgb.shape == (120, 160, 3)
    assert np.isfinite(r.rgb).all()
    assert sorted(x.name for x in tmp_path.iterdir()) == ["planes.exr", "planes.json"]


BAD = [
    (["nope"], "nope"),
    (["planes", "--camera", "nikon"], "nikon"),
    (["planes", "--fnumber", "0"], "'0'"),
    (["planes", "--fnumber", "-2.8"], "-2.8"),
    (["planes", "--fnumber", "nan"], "nan"),
    (["planes", "--focus-distance", "0.04"], "0.04"),
    (["planes", "--focus-distance", "0.05"], "0.05"),
    (["planes", "--focal-length", "300", "--focus-distance", "0.25"], "focus_distance_m=0.25"),
    (["planes", "--sensor-width", "0"], "'0'"),
    (["planes", "--sensor-height", "-24"], "-24"),
    (["planes", "--resolution", "640"], "640"),
    (["planes", "--resolution", "0x480"], "0x480"),
    (["planes", "--resolution", "axb"], "axb"),
    (["planes", "--resolution=-640x480"], "-640x480"),
    (["planes", "--preset", "huge"], "huge"),
    (["planes", "--spp", "0"], "'0'"),
    (["planes", "--spp", "-5"], "-5"),
    (["planes", "--spp", "many"], "many"),
    (["planes", "--sigma-convention", "fwhm"], "fwhm"),
    (["planes", "--output", "/nonexistent-dir/x.exr"], "/nonexistent-dir/x.exr"),
    (["planes", "-o", "{tmp}/not-a-folder.txt/x.exr"], "not-a-folder.txt"),
    (["planes", "--output", "{tmp}"], "{tmp}"),
    (["planes", "--out", "{tmp}/x.png"], "x.png"),
    ([], "SCENE"),
]


@pytest.mark.parametrize("args, named", BAD, ids=[" ".join(a) or "no-args" for a, _ in BAD])
def test_bad_input_one_line_exit_2_nothing_written(env, tmp_path, args, named):
    (tmp_path / "not-a-folder.txt").write_text("x")
    args = [a.replace("{tmp}", str(tmp_path)) for a in args]
    named = named.replace("{tmp}", str(tmp_path))
    before = sorted(p.name for p in tmp_path.iterdir())
    renders_before = _renders(env)
    p = run_here([*args, "--quiet"] if args else args, env)
    assert p.returncode == 2, (p.stdout, p.stderr)
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1, p.stderr
    assert "Traceback" not in p.stderr and named in lines[0]
    assert "allowed" in lines[0] or "choose" in lines[0] or "not allowed" in lines[0] or "invalid choice" in lines[0]
    assert p.stdout == ""
    assert sorted(q.name for q in tmp_path.iterdir()) == before
    assert _renders(env) == renders_before
