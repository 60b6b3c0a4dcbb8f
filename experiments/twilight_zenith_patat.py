"""The zenith twilight sky in V against the Paranal measurements of Patat et al. (2006).

Patat, Ugolnikov & Postylyakov (2006, A&A 455, 385, doi:10.1051/0004-6361:20064992)
measured the zenith twilight surface brightness at ESO-Paranal (2635 m) on more than 2000
FORS1 images and fitted, for the Sun's zenith distance ζ from 95° to 105°,

    m_V(ζ) = 11.84 + 1.518 (ζ − 95) − 0.057 (ζ − 95)²   [mag arcsec⁻²],

which includes the night sky (it levels off near 21.3–21.8 at 105°). The same authors find
Paranal's V twilight about 30 % fainter than at a low-altitude site.

The model: :class:`skytorch.Scene` at Paranal (24.627° S, 70.404° W, 2635 m) looking at
the zenith (``view="directions"``) through the evening twilight of 2024-04-07 (the Moon
below the horizon, one day before new Moon), 470–700 nm every 10 nm, total V surface
brightness (the sunlit sky with its multiple scattering plus the natural night sky,
``natural_model="garstang1989"``, 22.0 at the zenith) and the sunlit sky alone. The
atmosphere is the scene's default (turbidity 2, 300 DU) at the "default" and "reference"
fidelity; the sensitivities to turbidity 1 (no aerosol) and 3, to 250 DU of ozone and to
the observer's height (sea level instead of 2635 m, Patat et al.'s comparison of Paranal
with a low site) are shown at the reference fidelity. Nothing is fitted.

Output: ``twilight_zenith_patat.nc`` / ``.png``; ``--quick`` runs the default fidelity at
95°, 99° and 103° only.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import parse_arguments, save_outputs  # noqa: E402

#: ESO-Paranal: latitude, longitude [degree], height [m]
PARANAL = (-24.627, -70.404, 2635.0)
#: the evening searched for the Sun's zenith distances (UTC; the Moon below the horizon)
EVENING = (np.datetime64("2024-04-07T22:30"), np.datetime64("2024-04-08T00:00"))
#: Patat et al. (2006) V fit: a0 + a1 (ζ − 95) + a2 (ζ − 95)² [mag arcsec-2], 95° <= ζ <= 105°
PATAT_V = (11.84, 1.518, -0.057)
#: (label, fidelity, turbidity, ozone [DU], observer height [m])
CASES = (("default", "default", 2.0, 300.0, PARANAL[2]),
         ("reference", "reference", 2.0, 300.0, PARANAL[2]),
         ("reference, turbidity 1", "reference", 1.0, 300.0, PARANAL[2]),
         ("reference, turbidity 3", "reference", 3.0, 300.0, PARANAL[2]),
         ("reference, 250 DU", "reference", 2.0, 250.0, PARANAL[2]),
         ("reference, sea level", "reference", 2.0, 300.0, 0.0))


def patat_v(sun_zenith_deg):
    """Patat et al. (2006) zenith V twilight brightness [mag arcsec-2] (95-105 deg)."""
    d = np.asarray(sun_zenith_deg, dtype=float) - 95.0
    return PATAT_V[0] + PATAT_V[1] * d + PATAT_V[2] * d * d


def times_at(sun_zenith_deg):
    """UTC instants of the evening when the Sun's zenith distance takes the given values.

    Returns the instants and the Moon's altitude then [degree].
    """
    import skytorch as st

    lat, lon, height = PARANAL
    times = np.arange(*EVENING, np.timedelta64(1, "m"))
    ephemeris = st.ephemeris.sun_moon(times, lat_deg=lat, lon_deg=lon, elevation_m=height)
    zenith = 90.0 - ephemeris.sun_altitude.values
    seconds = (times - times[0]) / np.timedelta64(1, "s")
    at = np.interp(sun_zenith_deg, zenith, seconds)
    instants = [times[0] + np.timedelta64(int(round(t)), "s") for t in at]
    return instants, np.interp(at, seconds, ephemeris.moon_altitude.values)


def zenith_v(label_cases, sun_zenith_deg):
    """Total and sunlit-sky zenith V [mag arcsec-2] per case (case, sun_zenith)."""
    import skytorch as st

    lat, lon, _ = PARANAL
    wavelengths = tuple(float(w) for w in np.arange(470.0, 701.0, 10.0))
    instants, moon_altitude = times_at(sun_zenith_deg)
    total = np.zeros((len(label_cases), len(sun_zenith_deg)))
    sky = np.zeros_like(total)
    for i, (_, fidelity, turbidity, ozone, height) in enumerate(label_cases):
        scene = st.Scene(time=str(instants[0]), lat_deg=lat, lon_deg=lon, elevation_m=height,
                         view="directions",
                         directions={"altitude_deg": [90.0], "azimuth_deg": [0.0]},
                         wavelengths=wavelengths, turbidity=turbidity, ozone_du=ozone,
                         fidelity=fidelity)
        for j, instant in enumerate(instants):
            ds = scene.replace(time=str(instant)).render()
            total[i, j] = float(ds["v_mag_arcsec2"].values.reshape(-1)[0])
            sky[i, j] = float(ds["component_v_mag_arcsec2"].sel(component="sky")
                              .values.reshape(-1)[0])
    return total, sky, instants, moon_altitude


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    import matplotlib.pyplot as plt

    if arguments.quick:
        cases, sun_zenith = CASES[:1], np.array([95.0, 99.0, 103.0])
    else:
        cases, sun_zenith = CASES, np.arange(95.0, 105.5, 1.0)
    total, sky, instants, moon_altitude = zenith_v(cases, sun_zenith)
    observed = patat_v(sun_zenith)
    labels = [c[0] for c in cases]
    dims = ("case", "sun_zenith")
    dataset = xr.Dataset(
        {"model_v": (dims, total, {"units": "mag arcsec-2", "long_name": "modelled zenith "
                                   "V surface brightness, sunlit sky and night sky"}),
         "model_sunlit_v": (dims, sky, {"units": "mag arcsec-2", "long_name": "modelled "
                                        "zenith V surface brightness of the sunlit sky"}),
         "patat2006_v": ("sun_zenith", observed,
                         {"units": "mag arcsec-2", "long_name": "Patat et al. 2006 fit of "
                          "the Paranal zenith V twilight brightness"}),
         "difference": (dims, total - observed[None, :],
                        {"units": "mag", "long_name": "model minus Patat et al. 2006 "
                         "(positive: the model is fainter)"}),
         "time": ("sun_zenith", np.array(instants, dtype="datetime64[ns]"),
                  {"long_name": "UTC instant of the Sun's zenith distance"}),
         "moon_altitude": ("sun_zenith", moon_altitude,
                           {"units": "degree", "long_name": "the Moon's altitude"}),
         "fidelity": ("case", [c[1] for c in cases]),
         "turbidity": ("case", [c[2] for c in cases], {"units": "1"}),
         "ozone_du": ("case", [c[3] for c in cases], {"units": "DU"}),
         "observer_height": ("case", [c[4] for c in cases], {"units": "m"})},
        coords={"case": ("case", labels),
                "sun_zenith": ("sun_zenith", sun_zenith, {"units": "degree"})},
        attrs={"title": "Zenith twilight V at Paranal: skytorch against Patat et al. 2006",
               "site": "ESO-Paranal 24.627 S, 70.404 W, 2635 m",
               "references": "Patat, Ugolnikov & Postylyakov 2006, A&A 455, 385, "
                             "doi:10.1051/0004-6361:20064992"})
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(6, 6), sharex=True,
                                         gridspec_kw={"height_ratios": (2, 1)})
    top.plot(sun_zenith, observed, "k-", lw=2, label="Patat et al. 2006 (fit, Paranal)")
    for i, label in enumerate(labels):
        top.plot(sun_zenith, total[i], "o-", ms=3, label=f"skytorch {label}")
        bottom.plot(sun_zenith, total[i] - observed, "o-", ms=3)
    top.invert_yaxis()
    top.set_ylabel("zenith V [mag arcsec$^{-2}$]")
    top.legend(fontsize=7)
    bottom.axhline(0.0, color="k", lw=0.8)
    bottom.set_xlabel("Sun zenith distance [degree]")
    bottom.set_ylabel("model − Patat [mag]")
    save_outputs(dataset, figure, arguments.output_dir, "twilight_zenith_patat")
    header = "| case | " + " | ".join(f"{z:.0f}°" for z in sun_zenith) + " |"
    rows = [header, "| --- " * (len(sun_zenith) + 1) + "|",
            "| Patat et al. 2006 | " + " | ".join(f"{v:.2f}" for v in observed) + " |"]
    for i, label in enumerate(labels):
        cells = [f"{v:.2f} ({d:+.2f})"
                 for v, d in zip(total[i], total[i] - observed, strict=True)]
        rows.append(f"| {label} | " + " | ".join(cells) + " |")
    print("\n".join(rows))
    return dataset


if __name__ == "__main__":
    main()
