"""``skytorch eclipse``: lunar eclipses (a table, or one eclipse) and solar eclipses.

Examples
--------
::

    skytorch eclipse --from 2020-01-01 --to 2030-01-01 -o eclipses.nc
    skytorch eclipse 2015-09-28 -o eclipse.nc --png eclipse.png
    skytorch eclipse --solar 2026-08-12 --lat 42.34 --lon -3.70 --elevation 850 \
        -o burgos.nc --map obscuration.png --sky sky.png

Solar mode (``--solar DATE --lat --lon``) prints the local circumstances of the solar
eclipse nearest DATE (:func:`skytorch.eclipse.solar_eclipse_local`) and writes them
(``-o``, netCDF), the obscuration over the globe at the local maximum
(:func:`skytorch.eclipse.obscuration_map`, ``--map`` PNG) and an all-sky render at the
local maximum (:class:`skytorch.Scene`, the sky with the Sun's visible fraction at every
scattering point; ``--sky`` PNG, its Dataset beside it as ``<sky>.nc``).

Table mode (``--from/--to``) prints every eclipse with its greatest eclipse, kind,
magnitudes, gamma and durations, and writes the :func:`skytorch.eclipse.lunar_eclipses`
Dataset. Single-date mode (``DATE``) describes the eclipse nearest to that date: with the
light-curve model (:func:`skytorch.eclipse.lunar.lunar_eclipse`) when it is available,
otherwise its circumstances (greatest eclipse and contacts).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import math

import numpy as np

logger = logging.getLogger(__name__)


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the arguments of ``skytorch eclipse``."""
    parser.add_argument("date", nargs="?",
                        help="date (UTC) of one eclipse, e.g. 2015-09-28 (single-date mode)")
    parser.add_argument("--from", dest="start", metavar="START",
                        help="start of the range (UTC) for a table of eclipses")
    parser.add_argument("--to", dest="end", metavar="END", help="end of the range (UTC)")
    parser.add_argument("--enlargement", default="danjon",
                        choices=("danjon", "chauvenet", "none"),
                        help="shadow enlargement convention (default danjon, as the NASA canon)")
    parser.add_argument("-o", "--output", help="netCDF file to write")
    parser.add_argument("--png", help="PNG figure to write (single-date mode with light curve)")
    solar = parser.add_argument_group("solar eclipse (--solar DATE --lat LAT --lon LON)")
    solar.add_argument("--solar", metavar="DATE",
                       help="date (UTC) of a solar eclipse: local circumstances at --lat/--lon")
    solar.add_argument("--lat", type=float, help="observer's latitude [degree north]")
    solar.add_argument("--lon", type=float, help="observer's east longitude [degree]")
    solar.add_argument("--elevation", type=float, default=0.0,
                       help="observer's height above the ellipsoid [m] (default 0)")
    solar.add_argument("--map", help="PNG of the obscuration over the globe at the maximum")
    solar.add_argument("--sky", help="PNG of the all-sky render at the local maximum")
    solar.add_argument("--size", type=int, default=256,
                       help="pixels across the all-sky render (default 256)")
    solar.add_argument("--fidelity", default="default", choices=("fast", "default", "reference"),
                       help="fidelity preset of the render (default 'default')")


def format_table(dataset) -> str:
    """Format a fixed-width text table of eclipse circumstances (one line per eclipse)."""
    header = (f"{'greatest eclipse (UTC)':<21} {'kind':<9} {'umbral':>7} {'penumb.':>7} "
              f"{'gamma':>7} {'pen.min':>7} {'par.min':>7} {'tot.min':>7}")
    lines = [header, "-" * len(header)]

    def minutes(value) -> str:
        return "-" if np.isnan(value) else f"{value:.1f}"

    for index in range(dataset.sizes["eclipse"]):
        row = dataset.isel(eclipse=index)
        time = np.datetime_as_string(row.time.values, unit="s").replace("T", " ")
        lines.append(
            f"{time:<21} {str(row.kind.values):<9} {float(row.umbral_magnitude):7.4f} "
            f"{float(row.penumbral_magnitude):7.4f} {float(row.gamma):7.4f} "
            f"{minutes(float(row.penumbral_duration)):>7} "
            f"{minutes(float(row.partial_duration)):>7} {minutes(float(row.total_duration)):>7}"
        )
    return "\n".join(lines)


def _write(dataset, path: str | None) -> None:
    if path:
        from skytorch.dataset import to_netcdf

        print(f"wrote {to_netcdf(dataset, path)}")


def _run_table(args: argparse.Namespace) -> int:
    from skytorch.eclipse import lunar_eclipses

    if args.start is None or args.end is None:
        raise ValueError("table mode needs both --from START and --to END")
    dataset = lunar_eclipses(args.start, args.end, enlargement=args.enlargement)
    print(f"{dataset.sizes['eclipse']} lunar eclipses from {args.start} to {args.end} "
          f"(enlargement: {args.enlargement}; times UTC)")
    print(format_table(dataset))
    _write(dataset, args.output)
    return 0


def _light_curve_model():
    """``skytorch.eclipse.lunar.lunar_eclipse`` if that module is installed, else None."""
    try:
        module = importlib.import_module("skytorch.eclipse.lunar")
    except ModuleNotFoundError as error:
        if error.name == "skytorch.eclipse.lunar":
            return None
        raise
    return getattr(module, "lunar_eclipse", None)


def _run_light_curve(args: argparse.Namespace, model) -> int:
    """Single-date mode with the light-curve model: circumstances plus brightness."""
    dataset = model(args.date, enlargement=args.enlargement)
    print(_summary(dataset))
    _write(dataset, args.output)
    if args.png:
        from skytorch.eclipse.lunar import plot_lunar_eclipse

        plot_lunar_eclipse(dataset, args.png)
        print(f"wrote {args.png}")
    return 0


def _summary(dataset) -> str:
    """Circumstances and brightness of a light-curve Dataset, one item per line."""
    attrs = dataset.attrs
    lines = [f"lunar eclipse {attrs.get('parameter_greatest_eclipse')} UTC "
             f"({attrs.get('parameter_kind')}, umbral magnitude "
             f"{float(attrs.get('parameter_umbral_magnitude')):.4f})"]
    for name in ("p1", "u1", "u2", "u3", "u4", "p4"):
        lines.append(f"  {name.upper():<9} {attrs.get('parameter_' + name)}")
    danjon = attrs.get("parameter_danjon_l", "none")
    if danjon == "none":
        danjon = "none (not total)"
    elif math.isnan(float(danjon)):
        danjon = "none (V outside Vital's relation, [-3.8, 4.2] mag)"
    else:
        danjon = f"{float(danjon):.1f} +- 0.4"
    lines.append(f"  V at greatest eclipse {float(attrs['parameter_greatest_v_magnitude']):.2f}"
                 f" mag; Danjon L {danjon} (Vital's correlation)")
    return "\n".join(lines)


def _run_circumstances(args: argparse.Namespace) -> int:
    """Single-date mode without the light-curve model: circumstances and contacts."""
    if args.png:
        raise ValueError("--png needs the lunar-eclipse light-curve model")
    from skytorch.eclipse.lunar import nearest_eclipse

    dataset = nearest_eclipse(args.date, args.enlargement)
    print(format_table(dataset))
    row = dataset.isel(eclipse=0)
    for name in ("p1", "u1", "u2", "time", "u3", "u4", "p4"):
        value = row[name].values
        label = "greatest" if name == "time" else name.upper()
        text = "-" if np.isnat(value) else np.datetime_as_string(value, unit="s")
        print(f"  {label:<9} {text}")
    _write(dataset, args.output)
    return 0


def _solar_summary(local) -> str:
    """Local circumstances of one observer, one item per line."""
    def when(name):
        value = local[name].values
        return "-" if np.isnat(value) else np.datetime_as_string(value, unit="s")

    lines = [f"solar eclipse (greatest eclipse {local.attrs.get('greatest_eclipse')} UTC): "
             f"{local.kind.values} here, magnitude {float(local.magnitude):.4f}, obscuration "
             f"{float(local.obscuration):.4f}"]
    for name, label in (("c1", "C1"), ("c2", "C2"), ("maximum_time", "maximum"),
                        ("c3", "C3"), ("c4", "C4")):
        lines.append(f"  {label:<8} {when(name)}")
    duration = float(local.central_duration)
    if not np.isnan(duration):
        lines.append(f"  central phase {duration:.1f} s")
    return "\n".join(lines)


def _obscuration_png(dataset, path, observer, instant: str) -> None:
    """Write the obscuration map (latitude, longitude) as a PNG with the observer marked."""
    from skytorch.plot import obscuration_map, savefig

    axes = obscuration_map(dataset, observer=observer,
                           title=f"obscuration at {instant} UTC (day side)")
    figure = axes.figure
    savefig(figure, path)


def _run_solar(args: argparse.Namespace) -> int:
    """Solar mode: local circumstances, the obscuration map and the sky at the maximum."""
    from skytorch.eclipse import obscuration_map, solar_eclipse_local

    if args.lat is None or args.lon is None:
        raise ValueError("--solar needs --lat and --lon")
    if args.date is not None or args.start or args.end:
        raise ValueError("give --solar DATE alone, without DATE or --from/--to")
    local = solar_eclipse_local(args.solar, args.lat, args.lon, args.elevation)
    print(_solar_summary(local))
    _write(local, args.output)
    maximum = local.maximum_time.values
    if np.isnat(maximum):
        if args.map or args.sky:
            raise ValueError(f"no eclipse at latitude {args.lat}, longitude {args.lon}: "
                             "no maximum to map or render")
        return 0
    instant = np.datetime_as_string(maximum, unit="s")
    if args.map:
        lat = np.arange(-89.75, 90.0, 0.5)
        lon = np.arange(-179.75, 180.0, 0.5)
        _obscuration_png(obscuration_map(instant, lat, lon), args.map, (args.lat, args.lon),
                         instant)
        print(f"wrote {args.map}")
    if args.sky:
        from pathlib import Path

        from skytorch.dataset import to_netcdf
        from skytorch.scene import Scene, scene_png

        scene = Scene(time=instant, lat_deg=args.lat, lon_deg=args.lon,
                      elevation_m=args.elevation, view="fisheye", size=args.size,
                      fidelity=args.fidelity)
        frame = scene.render()
        print(f"sky at {instant} UTC: {frame.attrs['effects_computed']}")
        print(f"wrote {scene_png(frame, args.sky, title=f'{instant} UTC')}")
        print(f"wrote {to_netcdf(frame, Path(args.sky).with_suffix('.nc'))}")
    return 0


def run(args: argparse.Namespace) -> int:
    """Run ``skytorch eclipse``."""
    if args.solar is not None:
        return _run_solar(args)
    if args.date is not None and (args.start or args.end):
        raise ValueError("give either DATE or --from/--to, not both")
    if args.date is None:
        return _run_table(args)
    model = _light_curve_model()
    if model is None:
        logger.info("light-curve model not available: circumstances only")
        return _run_circumstances(args)
    return _run_light_curve(args, model)
