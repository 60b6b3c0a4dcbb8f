"""netCDF storage of a scene render: error, file size and write time versus significant digits.

A night all-sky render (the 2015-09-28 totality over Berlin with a synthetic city, as in
the demo) is written with :func:`skytorch.to_netcdf` losslessly (``significant_digits``
None), uncompressed, and with 3 to 12 significant digits of granular bit rounding. For
each setting the file is read back and compared with the in-memory render: the largest
relative error of the radiances (``radiance``, ``component_radiance``, ``xyz``) and the
largest absolute error of the surface brightnesses ``v_mag_arcsec2`` [mag arcsec^-2]. The
cost is the file size and the median write time of three writes.

Usage: ``python experiments/netcdf_quantisation_accuracy_cost.py [--quick] [--output-dir DIR]``.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import xarray as xr

import skytorch as st
from experiments._common import parse_arguments, save_outputs
from skytorch.skyglow.citymap import synthetic_city

#: settings compared: "uncompressed", "lossless", then significant digits
DIGITS = (12, 9, 7, 5, 3)
RADIANCE_VARIABLES = ("radiance", "component_radiance", "xyz")
REPEATS = 3


def render(size: int) -> xr.Dataset:
    city = synthetic_city(extent_m=60_000.0, cell_m=1_000.0, population=1_000_000.0,
                          scale_length_m=4_000.0, centre_xy=(8_000.0, -9_000.0))
    scene = st.Scene(time="2015-09-28T02:47:00", lat_deg=52.52, lon_deg=13.40,
                     elevation_m=34.0, size=size, light_map=city, fidelity="fast")
    return scene.render()


def measure(ds: xr.Dataset, folder: Path, label: str, **options) -> dict[str, float]:
    path = folder / f"{label}.nc"
    seconds = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        st.to_netcdf(ds, path, **options)
        seconds.append(time.perf_counter() - start)
    back = st.open_dataset(path)
    relative = 0.0
    for name in RADIANCE_VARIABLES:
        if name in ds:
            exact, stored = ds[name].values, back[name].values
            scale = np.where(exact != 0.0, np.abs(exact), 1.0)
            relative = max(relative, float(np.max(np.abs(stored - exact) / scale)))
    finite = np.isfinite(ds["v_mag_arcsec2"].values)
    magnitude = float(np.max(np.abs(back["v_mag_arcsec2"].values[finite]
                                    - ds["v_mag_arcsec2"].values[finite])))
    return {"size_mb": path.stat().st_size / 1e6, "write_seconds": float(np.median(seconds)),
            "radiance_relative_error": relative, "v_mag_error": magnitude}


def main(argv=None):
    args = parse_arguments(__doc__.splitlines()[0], argv)
    size = 48 if args.quick else 384
    ds = render(size)
    settings = {"uncompressed": {"compress": False}, "lossless": {}}
    settings.update({f"digits_{n}": {"significant_digits": n} for n in DIGITS})
    with tempfile.TemporaryDirectory() as folder:
        rows = {label: measure(ds, Path(folder), label, **options)
                for label, options in settings.items()}
    labels = list(rows)
    digits = [np.nan, np.nan, *DIGITS]
    result = xr.Dataset(
        {name: ("setting", [rows[label][name] for label in labels])
         for name in ("size_mb", "write_seconds", "radiance_relative_error", "v_mag_error")},
        coords={"setting": labels, "significant_digits": ("setting", digits)})
    result["size_mb"].attrs.update(units="MB", long_name="file size")
    result["write_seconds"].attrs.update(units="s", long_name="write time (median of 3)")
    result["radiance_relative_error"].attrs.update(
        units="1", long_name="largest relative error of the radiances read back")
    result["v_mag_error"].attrs.update(
        units="mag arcsec-2", long_name="largest error of v_mag_arcsec2 read back")
    result["significant_digits"].attrs.update(units="1", long_name="significant digits kept")
    result.attrs.update(title="to_netcdf: error, size and write time of a scene render",
                        image_pixels=f"{size} x {size}",
                        uncompressed_mb=rows["uncompressed"]["size_mb"])

    figure, (axis, cost_axis) = plt.subplots(1, 2, figsize=(11, 4.5))
    n = np.array(DIGITS, dtype=float)
    quantised = [f"digits_{d}" for d in DIGITS]
    axis.semilogy(n, [rows[q]["radiance_relative_error"] for q in quantised], "o-",
                  label="radiance, max relative error")
    axis.semilogy(n, [rows[q]["v_mag_error"] for q in quantised], "s-",
                  label="V surface brightness, max error [mag]")
    axis.semilogy(n, 5.0 * 10.0 ** -n, "k:", label="bound 5·10^-N")
    axis.set_xlabel("significant digits N")
    axis.set_ylabel("error")
    axis.set_title(f"{size}² render read back")
    axis.legend(fontsize=8)
    raw = rows["uncompressed"]["size_mb"]
    cost_axis.plot(n, [raw / rows[q]["size_mb"] for q in quantised], "o-",
                   label="quantised + zlib")
    cost_axis.axhline(raw / rows["lossless"]["size_mb"], color="tab:green", ls="--",
                      label="lossless zlib")
    cost_axis.set_xlabel("significant digits N")
    cost_axis.set_ylabel("size reduction (uncompressed / file)")
    cost_axis.set_title("file size")
    cost_axis.legend(fontsize=8)
    paths = save_outputs(result, figure, args.output_dir, "netcdf_quantisation_accuracy_cost")
    print(result.to_dataframe().to_string())
    return paths


if __name__ == "__main__":
    main()
