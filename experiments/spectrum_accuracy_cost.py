"""Colour from coarse spectral grids: chromaticity error versus cost.

For test spectra (black bodies at 3000, 5800 and 10000 K; a sunlit Rayleigh sky, solar
spectrum × λ^-4) sampled on grids of 3 ("rgb"), 5, 8, 15 ("bands15"), 30 equal bands
and the 5-nm CIE grid, the CIE 1931 chromaticity from ``spectrum_to_xyz`` is compared
with the same spectrum integrated in float64 on the 1-nm CIE grid, for both
reconstructions (``reference="none"``/``"solar"``) and both dtypes. The cost is the wall
time to convert a batch of spectra. Run with ``st.sweep`` over the four knobs.

Usage: ``python experiments/spectrum_accuracy_cost.py [--quick] [--output-dir DIR]``.
"""

from __future__ import annotations

import time

import matplotlib.pyplot as plt
import numpy as np
import torch

import skytorch as st
from experiments._common import parse_arguments, save_outputs
from skytorch import spectrum

SPECTRA = ("blackbody_3000K", "blackbody_5800K", "blackbody_10000K", "rayleigh_sky")
GRIDS = ("rgb", "bands5", "bands8", "bands15", "bands30", "cie5")
DTYPES = {"float64": torch.float64, "float32": torch.float32}


def grid_wavelengths(name: str) -> torch.Tensor:
    """Wavelengths [nm] of a named grid (``bandsN``: centres of N equal bands 360–830 nm)."""
    if name in spectrum.WAVELENGTH_PRESETS:
        return spectrum.wavelength_grid(name)
    count = int(name.removeprefix("bands"))
    width = (830.0 - 360.0) / count
    return 360.0 + width * (torch.arange(count, dtype=torch.float64) + 0.5)


def test_spectrum(name: str, wavelength_nm: torch.Tensor) -> torch.Tensor:
    if name.startswith("blackbody"):
        temperature = float(name.split("_")[1].rstrip("K"))
        return spectrum.blackbody_radiance(wavelength_nm, temperature)
    return spectrum.solar_irradiance(wavelength_nm) * (wavelength_nm / 550.0) ** -4


def chromaticity(xyz: torch.Tensor) -> torch.Tensor:
    return xyz[..., :2] / xyz.sum(-1, keepdim=True)


def make_case(batch: int):
    fine = spectrum.wavelength_grid("cie1")

    def case(grid, spectrum_kind, reference, dtype):
        wavelength = grid_wavelengths(grid)
        reference_xy = chromaticity(spectrum.spectrum_to_xyz(test_spectrum(spectrum_kind, fine),
                                                             fine))
        values = test_spectrum(spectrum_kind, wavelength).to(DTYPES[dtype])
        xy = chromaticity(spectrum.spectrum_to_xyz(values, wavelength.to(DTYPES[dtype]),
                                                   reference=reference))
        error = float((xy.double() - reference_xy).abs().max())
        batch_values = values.expand(batch, -1).contiguous()
        spectrum.spectrum_to_xyz(batch_values, wavelength, reference=reference)  # warm cache
        start = time.perf_counter()
        spectrum.spectrum_to_xyz(batch_values, wavelength, reference=reference)
        seconds = time.perf_counter() - start
        return {"chromaticity_error": error, "seconds": seconds}

    return case


def main(argv=None):
    args = parse_arguments(__doc__.splitlines()[0], argv)
    grids = ("rgb", "cie5") if args.quick else GRIDS
    batch = 100 if args.quick else 1_000_000
    ds = st.sweep(make_case(batch), progress=False, grid=list(grids), spectrum_kind=list(SPECTRA),
                  reference=list(spectrum.REFERENCES), dtype=list(DTYPES))
    ds["chromaticity_error"].attrs.update(
        units="1", long_name="chromaticity error",
        description="max |Δx|, |Δy| (CIE 1931) against the float64 integral on the 1-nm grid")
    ds["seconds"].attrs.update(
        units="s", long_name="conversion time",
        description=f"wall time of spectrum_to_xyz for a batch of {batch} spectra")
    ds.attrs["title"] = "spectrum_to_xyz: chromaticity error versus grid, reconstruction, dtype"
    ds.attrs["batch"] = batch

    counts = np.array([len(grid_wavelengths(g)) for g in grids])
    figure, (axis, cost_axis) = plt.subplots(1, 2, figsize=(11, 4.5))
    markers = {"none": "o", "solar": "s"}
    colours = dict(zip(SPECTRA, ("tab:red", "tab:orange", "tab:blue", "tab:green"),
                       strict=True))
    for name in SPECTRA:
        for reference in spectrum.REFERENCES:
            sel = ds.sel(spectrum_kind=name, reference=reference, dtype="float64")
            axis.loglog(counts, np.maximum(sel["chromaticity_error"].values, 1e-12),
                        marker=markers[reference], color=colours[name],
                        ls="-" if reference == "none" else ":",
                        label=f"{name}, reference={reference}")
    axis.axhline(1e-3, color="grey", lw=0.8, ls="--")
    axis.set_xlabel("number of wavelengths (" + ", ".join(grids) + ")")
    axis.set_ylabel("chromaticity error (max |Δx|, |Δy|)")
    axis.set_title("colour from coarse grids vs 1-nm integral")
    axis.legend(fontsize=7)
    for dtype in DTYPES:
        seconds = ds["seconds"].sel(dtype=dtype).median(("spectrum_kind", "reference"))
        cost_axis.loglog(counts, seconds.values, marker="o", label=dtype)
    cost_axis.set_xlabel("number of wavelengths")
    cost_axis.set_ylabel(f"time for {batch} spectra [s] (median over spectra)")
    cost_axis.set_title("cost of spectrum_to_xyz")
    cost_axis.legend()
    paths = save_outputs(ds, figure, args.output_dir, "spectrum_accuracy_cost")
    print(ds["chromaticity_error"].sel(dtype="float64", drop=True).to_pandas()
          if ds["chromaticity_error"].ndim == 2 else
          ds["chromaticity_error"].sel(dtype="float64", drop=True).to_dataframe()
          .unstack("reference"))
    return paths


if __name__ == "__main__":
    main()
