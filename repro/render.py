"""Render a test scene with its ground truth (EXR: RGB, Z, coc, sigma, masks + JSON sidecar).

Examples
--------
python -m repro.render --list
python -m repro.render planes --scene-size small --fnumber 4
python -m repro.render portrait --resolution 320x240 --spp 64 -o portrait.exr

Bad input (unknown scene or camera, f-number <= 0, focus distance <= focal length, bad sensor size
or resolution, spp <= 0, unwritable -o/--output) prints one line on stderr and exits with status 2
before anything is rendered or written.
"""

from __future__ import annotations

import sys

from repro._cli import (
    ArgumentParser,
    CLIError,
    add_force_option,
    add_quiet_option,
    add_scene_size_option,
    add_variant_option,
    check_output_path,
    float_type,
    hidden_alias,
    int_type,
    parse_resolution,
    run_cli,
    user_input,
)

PROG = "python -m repro.render"


def _parser() -> ArgumentParser:
    from scenes.camera import CAMERA_PRESETS
    from scenes.library import SCENES
    from scenes.thin_lens import SIGMA_CONVENTIONS

    p = ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    p.add_argument("scene", nargs="?", metavar="SCENE", help=f"scene name: {', '.join(SCENES)} (details: --list)")
    p.add_argument("--list", action="store_true",
                   help="list the scenes (set, camera, description, sigma_gt range per render size and f-number "
                        "measured from the ground truth, cached) and exit")
    p.add_argument("--camera", default=None, metavar="PRESET",
                   help=f"camera preset, one of {', '.join(CAMERA_PRESETS)} (default: the scene's own camera; the "
                        "sensor presets keep the 50 mm full-frame field of view, the paper's cameras their lens)")
    p.add_argument("--fnumber", type=float_type("--fnumber"), default=None, metavar="N",
                   help="f-number N > 0 (default 8)")
    p.add_argument("--focus-distance", type=float_type("--focus-distance"), default=None,
                   metavar="M", help="focus distance in metres, > focal length (default: the scene's)")
    p.add_argument("--focal-length", type=float_type("--focal-length"), default=None,
                   metavar="MM", help="focal length in mm (default: the camera preset's)")
    p.add_argument("--sensor-width", type=float_type("--sensor-width"), default=None,
                   metavar="MM", help="sensor width in mm (default: the camera preset's)")
    p.add_argument("--sensor-height", type=float_type("--sensor-height"), default=None,
                   metavar="MM", help="sensor height in mm (default: the camera preset's)")
    size = p.add_mutually_exclusive_group()
    size.add_argument("--resolution", default=None, metavar="WxH",
                      help="image size in pixels, e.g. 640x480 (instead of --scene-size)")
    add_scene_size_option(size, default=None, aliases=("--preset", "--scene-preset"),
                          what="render size (default small; with --resolution, the size whose spp is the default)")
    p.add_argument("--spp", type=int_type("--spp"), default=None, metavar="K",
                   help="samples per pixel, >= 1 (default: the scene's for the render size)")
    p.add_argument("--seed", type=int_type("--seed", minimum=0), default=0, metavar="S", help="sampler seed (default 0)")
    add_variant_option(p)
    p.add_argument("--sigma-convention", default="line_spread", choices=sorted(SIGMA_CONVENTIONS),
                   help="CoC to sigma: line_spread (c/4, default) or erf_fit (0.273 c)")
    p.add_argument("-o", "--output", default=None, metavar="FILE", help="also write the EXR here (+ .json sidecar)")
    hidden_alias(p, "--out", dest="output")
    add_force_option(p, what="re-render even when the render is cached (the new render replaces it)")
    add_quiet_option(p, what="no progress bar")
    return p


def _list_scenes(scenes, *, variant=None, progress=True) -> int:
    """Print every scene: its set, camera, focus and σ_gt range per render size and f-number (measured)."""
    from tqdm.auto import tqdm

    from scenes.library import DEFAULT_F_NUMBERS, PRESETS, SCENE_SETS
    from scenes.library.ranges import sigma_gt_ranges

    set_of = {n: s for s, names in SCENE_SETS.items() for n in names}
    lines = []
    for name, sdef in tqdm(list(scenes.items()), desc="sigma_gt ranges (ground-truth depth per render size)",
                           unit="scene", disable=not progress, leave=False):
        cam = sdef.camera("full")
        ranges = sigma_gt_ranges(sdef, variant=variant)
        lines.append(f"{name}  [{set_of.get(name, '-')}]  {sdef.description}")
        lines.append(f"    camera {sdef.camera_name}: sensor {cam.sensor_width_mm:g}x{cam.sensor_height_mm:g} mm, "
                     f"f = {cam.focal_length_mm:g} mm, focus {sdef.focus_distance_m:g} m, "
                     f"fov {cam.fov_x_deg:.1f} deg")
        for preset, (w, h) in PRESETS.items():
            r = ranges[preset]
            cells = "   ".join(
                f"f/{n:g} {r['f_numbers'][f'{n:g}']['min_px']:.2f}-{r['f_numbers'][f'{n:g}']['max_px']:.2f} px "
                f"(p95 {r['f_numbers'][f'{n:g}']['p95_px']:.2f})" for n in DEFAULT_F_NUMBERS)
            depth = r["depth_m"]
            lines.append(f"    {preset:<5} {w}x{h}: sigma_gt {cells}; depth "
                         + (f"{depth[0]:.3g}-{depth[1]:.3g} m" if depth else "none"))
    print("\n".join(lines))
    print("sigma_gt measured from each scene's ground truth (lens-centre-ray depth, Eq. 5, box filter; "
          "line_spread convention); scene sets: " + ", ".join(SCENE_SETS))
    return 0


def main(argv=None) -> int:
    """Entry point; returns the exit status (user errors raise CLIError, see repro._cli)."""
    args = _parser().parse_args(argv)
    from scenes.library import SCENES

    if args.list:
        return _list_scenes(SCENES, variant=args.variant, progress=not args.quiet)
    if args.scene is None:
        raise CLIError(f"SCENE is missing; allowed: one of {sorted(SCENES)} (or --list)")
    sdef, camera, preset, out = _validated(args)
    from scenes.render import render_scene

    render = render_scene(sdef, camera, preset=preset, spp=args.spp, seed=args.seed, variant=args.variant,
                          sigma_convention=args.sigma_convention, force=args.force,
                          progress=not args.quiet)
    if out is not None:
        render.save(out)
        where = out
    elif render.path is not None:
        where = render.path
    else:
        where = None
    m = render.metadata
    st = m["stats"]
    w, h = m["resolution"]
    if where is not None:
        print(f"wrote {where} (+ {where.with_suffix('.json').name})")
    print(
        f"{m['scene']} v{m['scene_version']} {w}x{h} f/{camera.f_number:g} D={camera.focus_distance_m:g} m "
        f"spp={m['spp']} {m['variant']}: sigma_gt {st['sigma_px_min']:.2f}-{st['sigma_px_max']:.2f} px "
        f"(median {st['sigma_px_median']:.2f}, {m['sigma_convention']}), depth "
        f"{st['depth_min_m']:.3g}-{st['depth_max_m']:.3g} m, occlusion boundary "
        f"{100 * st['occlusion_boundary_fraction']:.0f}%, render {m['render_time_s']:.1f} s"
    )
    return 0


def _validated(args):
    """(scene, camera, render size, --out path) of the command line, every flag checked before any render."""
    from scenes.library import get_scene
    from scenes.render import validate_render_options

    preset = args.scene_size or "small"
    resolution = parse_resolution(args.resolution) if args.resolution else None
    if resolution is not None and args.scene_size is None:
        preset = "full" if resolution[0] > 320 else "small"  # default spp only
    changes = {}
    for flag, field in (("focus_distance", "focus_distance_m"), ("focal_length", "focal_length_mm"),
                        ("sensor_width", "sensor_width_mm"), ("sensor_height", "sensor_height_mm")):
        value = getattr(args, flag)
        if value is not None:
            changes[field] = value
    with user_input():
        sdef = get_scene(args.scene)
        camera = sdef.camera(preset, f_number=args.fnumber, camera_name=args.camera, resolution=resolution,
                             **changes)
        validate_render_options(sdef, camera, preset=preset, spp=args.spp, seed=args.seed,
                                sigma_convention=args.sigma_convention)
    out = check_output_path(args.output, flag="--output") if args.output else None
    return sdef, camera, preset, out


if __name__ == "__main__":
    sys.exit(run_cli(main, prog=PROG))
