"""``skytorch render``: render a scene described in a TOML file.

Examples
--------
::

    skytorch render data/scene_example.toml -o sky.nc --png sky.png
    skytorch render scene.toml -o sky.nc --size 128 --fidelity fast --night

The TOML format is documented in ``docs/scene.md``; ``data/scene_example.toml`` is a
complete example. Options given on the command line override the file. With several
observers (lists in ``[observer]``) the plan is printed per observer and the PNG is
written once per observer (``sky_0.png``, ``sky_1.png``, ...).
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

logger = logging.getLogger(__name__)


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of ``skytorch render``."""
    parser.add_argument("scene", help="TOML scene file")
    parser.add_argument("-o", "--output", required=True,
                        help="netCDF file to write (a *.zarr path writes a Zarr store)")
    parser.add_argument("--png", help="also write the tone-mapped image to this PNG file")
    parser.add_argument("--size", type=int, help="override the view size [pixels]")
    parser.add_argument("--fidelity", choices=("fast", "default", "reference"),
                        help="override the fidelity preset")
    parser.add_argument("--exposure", type=float,
                        help="exposure [cd^-1 m^2] of the PNG (default automatic)")
    parser.add_argument("--night", action="store_true",
                        help="night-vision (Purkinje) rendering of the PNG")


def _check_outputs(args: argparse.Namespace, scene) -> None:
    """ValueError for output options that would fail after the render."""
    from skytorch._validate import check_positive

    if Path(args.output).is_dir() and not str(args.output).endswith(".zarr"):
        raise ValueError(f"-o {args.output}: is a directory; give a file name")
    if args.exposure is not None:
        check_positive("--exposure", args.exposure, unit=" cd^-1 m^2")
        if not args.png:
            raise ValueError("--exposure sets the PNG's exposure: give --png too")
    if args.night and not args.png:
        raise ValueError("--night renders the PNG: give --png too")
    if args.png:
        if "xyz" not in scene.outputs:
            raise ValueError(f"--png tone-maps the 'xyz' output; the scene's outputs are "
                             f"{list(scene.outputs)} (add \"xyz\")")
        if scene.view not in ("fisheye", "panorama", "camera"):
            raise ValueError(f"--png needs an image view (fisheye, panorama or camera); "
                             f"the scene's view is {scene.view!r}")


def run(args: argparse.Namespace) -> int:
    """Render the scene, write netCDF (and PNG), print the plan."""
    from skytorch.dataset import write_dataset
    from skytorch.scene import Scene, scene_png

    scene = Scene.from_toml(args.scene)
    changes = {k: v for k, v in (("size", args.size), ("fidelity", args.fidelity))
               if v is not None}
    if changes:
        scene = scene.replace(**changes)
    _check_outputs(args, scene)  # before the render: nothing written for a bad option
    ds = scene.render()
    path = write_dataset(ds, args.output)
    frames = ([ds.isel(observer=i) for i in range(ds.sizes["observer"])]
              if "observer" in ds.dims else [ds])
    for index, frame in enumerate(frames):
        label = f"observer {index}: " if len(frames) > 1 else ""
        computed = (frame["effects_computed"].item() if "effects_computed" in frame
                    else frame.attrs["effects_computed"])
        skipped = (frame["effects_skipped"].item() if "effects_skipped" in frame
                   else frame.attrs["effects_skipped"])
        print(f"{label}computed: {computed}")
        print(f"{label}skipped: {skipped}")
    print(f"wrote {path}")
    if args.png:
        for index, frame in enumerate(frames):
            target = Path(args.png)
            if len(frames) > 1:  # one image per observer: sky_0.png, sky_1.png, ...
                target = target.with_name(f"{target.stem}_{index}{target.suffix}")
            png = scene_png(frame, target, exposure=args.exposure, night=args.night)
            print(f"wrote {png}")
    return 0
