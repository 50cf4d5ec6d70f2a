"""Export the rendered scenes as a versioned dataset (see :mod:`experiments.dataset` and docs/dataset.md).

``python -m repro.dataset export [--scenes NAME ...] [--fnumber N ...] [--scene-size small|full]
[--camera PRESET] [--noise LEVEL] [--jpeg Q] [--force] --out DIR [-q]``
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

PROG = "python -m repro.dataset"


def _parser():
    from repro._cli import (ArgumentParser, add_force_option, add_quiet_option, add_scene_size_option,
                            add_variant_option, float_type, int_type)
    from scenes.display import NOISE_LEVELS

    p = ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    p.add_argument("command", choices=("export",), help="export: write the renders and their ground truth to DIR")
    add_variant_option(p)
    p.add_argument("--scenes", nargs="+", default=None, metavar="NAME", help="scenes (default: all)")
    p.add_argument("--fnumber", nargs="+", type=float_type("--fnumber"), default=[8.0, 4.0], metavar="N",
                   help="apertures (default: 8 4)")
    add_scene_size_option(p)
    p.add_argument("--camera", default=None, metavar="PRESET",
                   help="camera preset of scenes.CAMERA_PRESETS (default: each scene's own camera); one per "
                        "dataset folder, recorded in the manifest")
    p.add_argument("--noise", default="none", metavar="LEVEL",
                   help=f"sensor noise of the camera pipeline in the 8/16-bit images ({', '.join(NOISE_LEVELS)}; "
                        "default none; drawn from a seed of each image's name)")
    p.add_argument("--jpeg", type=int_type("--jpeg", minimum=1), default=None, metavar="Q",
                   help="JPEG quality 1-100 of the 8-bit image (default: none)")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="dataset folder")
    add_force_option(p, what="re-render and re-export every image, even those the folder (or the render cache) holds")
    add_quiet_option(p, what="no progress display")
    return p


def main(argv=None) -> int:
    """Entry point; returns the exit status."""
    args = _parser().parse_args(argv)
    from tqdm import tqdm

    from experiments import dataset as ds
    from experiments.cache_keys import code_fingerprint
    from experiments.registry import library_versions
    from method.registry import Registry
    from repro._cli import CLIError, require_extras, scene_grid, user_input, version_string
    from scenes import get_scene
    from scenes.camera import CAMERA_PRESETS as CAMERAS

    CAMERA_PRESETS = Registry("camera preset", CAMERAS)

    from scenes.display import check_jpeg_quality, check_noise_level

    scenes, f_numbers = scene_grid(args.scenes, args.fnumber, args.scene_size, out=args.out)
    with user_input():
        camera_name = None if args.camera is None else CAMERA_PRESETS.check(args.camera, what="--camera")
        check_noise_level(args.noise)
        if args.jpeg is not None:
            check_jpeg_quality(args.jpeg)
    pipeline = {"noise": args.noise, "jpeg_quality": args.jpeg}
    combos = [(s, n) for s in scenes for n in f_numbers]
    entries = []
    with tqdm(combos, desc="export", unit="image", file=sys.stderr, disable=args.quiet) as bar:
        for s, n in bar:
            name = ds.image_name(s, n, args.scene_size)
            if not args.force and ds.is_complete(args.out, name):
                entry = json.loads((args.out / "done" / f"{name}.json").read_text())
                if entry.get("camera_preset") != camera_name:
                    raise CLIError(f"{args.out}: {name} was exported with --camera {entry.get('camera_preset')}; "
                                     "allowed: the same --camera, or another --out folder")
                done = entry.get("camera_pipeline", {})
                if {"noise": done.get("noise", "none"), "jpeg_quality": done.get("jpeg_quality")} != pipeline:
                    raise CLIError(f"{args.out}: {name} was exported with another --noise / --jpeg; allowed: the "
                                     "same, or another --out folder")
                entries.append(entry)
                continue
            require_extras("render", command="repro.dataset export (renders not yet exported)")
            from scenes import render_scene

            camera = get_scene(s).camera(args.scene_size, f_number=n, camera_name=camera_name)
            render = render_scene(s, camera, preset=args.scene_size, variant=args.variant, force=args.force,
                                  progress=False)
            entries.append(ds.export_image(args.out, name, render, camera_preset=camera_name, noise=args.noise,
                                           jpeg_quality=args.jpeg))
    path = ds.write_manifest(args.out, entries,
                             render_settings={"scene_preset": args.scene_size, "camera_preset": camera_name,
                                              **pipeline},
                             harness={"version": version_string(), "git_commit": ds.git_commit(),
                                      "code": code_fingerprint(), "libraries": library_versions()})
    print(f"  {path}")
    return 0


if __name__ == "__main__":
    from repro._cli import run_cli

    sys.exit(run_cli(main, prog=PROG))
