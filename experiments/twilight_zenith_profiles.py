"""The zenith twilight at Paranal with the site's ozone and the AFGL model atmospheres.

``experiments/twilight_zenith_patat.py`` compares the scenes' atmosphere (turbidity 2 and
300 DU of ozone in a tent peaking at 25 km) with the zenith V twilight that Patat,
Ugolnikov & Postylyakov (2006, A&A 455, 385) measured at ESO-Paranal (2635 m): the model is
0.3–0.6 mag fainter. The deep twilight's light crosses the ozone layer along grazing paths,
where the Chappuis band absorbs, so the column and the height of the ozone matter. This
experiment computes the sunlit zenith sky (every order of scattering, on the scenes'
default multiple-scattering tables) for the tent at 300, 284 and 258 DU (258 DU: the
Paranal column of ESO's sky model, SkyCalc, Noll et al. 2012) and for the AFGL 1986 model
atmospheres as soundings (Anderson et al. 1986; their molecules, temperatures and ozone
profiles): tropical (284 DU, the nearest to Paranal's 24.6° S), the same scaled to 300 and
to 258 DU, mid-latitude summer (336 DU) and the U.S. Standard Atmosphere (346 DU); and,
since the grazing sunlight of the deep twilight crosses the stratosphere, the same with the
stratospheric sulfate layer of the measurements' years (the record's 1999–2005 mean, Sato
et al. 1993 / GloSSAC, in LOWTRAN 7's background profile) or LOWTRAN's own background
layer (0.0070 at 550 nm; the scenes' atmosphere has no stratospheric layer). Each is
compared with Patat et al.'s fit less a night sky of 21.6 V mag arcsec⁻² (Patat 2003, the
dark Paranal zenith): the scattered light alone, Sun zenith distance 95–102° (beyond, the
night sky is most of the fit and the subtraction uncertain). Nothing is fitted.

The differences between the atmospheres are the result: the tables' own error in the deep
twilight (docs/scene.md) is common to all of them.

Output: ``twilight_zenith_profiles.nc`` / ``.png``; ``--quick`` runs three atmospheres
(the tent at 300 and 258 DU, and at 300 DU with the stratospheric layer) at three Sun
zenith distances.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import parse_arguments, save_outputs  # noqa: E402
from experiments.twilight_zenith_patat import PARANAL, patat_v  # noqa: E402

#: the Paranal zenith night sky in V (Patat 2003, A&A 400, 1183) [mag arcsec-2]
NIGHT_SKY_V = 21.6
#: the ozone column of Paranal in ESO's sky model (SkyCalc) [DU]
PARANAL_OZONE_DU = 258.0
#: (label, AFGL profile or None for the tent, ozone column [DU] or None for the profile's)
#: years of the stratospheric record averaged for the measurements' stratosphere: FORS1
#: observed from 1999 on and the paper was submitted in February 2006
STRATOSPHERE_YEARS = range(1999, 2006)
#: the LOWTRAN 7 background stratospheric model's own optical depth at 550 nm (Shettle &
#: Fenn 1979, as tabulated in LOWTRAN 7)
LOWTRAN_BACKGROUND = "lowtran"
#: (label, AFGL profile or None for the tent, ozone column [DU] or None for the profile's,
#: stratospheric sulfate layer: None, "record" for the record's mean of STRATOSPHERE_YEARS
#: or LOWTRAN_BACKGROUND; the layer has LOWTRAN 7's background profile)
ATMOSPHERES = (("tent, 300 DU (scenes)", None, 300.0, None),
               ("tent, 258 DU", None, PARANAL_OZONE_DU, None),
               ("tent, 284 DU", None, 284.0, None),
               ("AFGL tropical (284 DU)", "tropical", None, None),
               ("AFGL tropical, 300 DU", "tropical", 300.0, None),
               ("AFGL tropical, 258 DU", "tropical", PARANAL_OZONE_DU, None),
               ("AFGL mid-latitude summer (336 DU)", "midlatitude_summer", None, None),
               ("AFGL U.S. Standard (346 DU)", "us_standard", None, None),
               ("tent, 300 DU + stratospheric background (record)", None, 300.0, "record"),
               ("AFGL tropical, 258 DU + stratospheric background (record)", "tropical",
                PARANAL_OZONE_DU, "record"),
               ("AFGL tropical, 258 DU + LOWTRAN background layer", "tropical",
                PARANAL_OZONE_DU, LOWTRAN_BACKGROUND))
TURBIDITY = 2.0


def stratospheric_depth(layer) -> float:
    """Vertical optical depth at 550 nm of a case's stratospheric layer [1]."""
    from skytorch.atmosphere.aerosol import stratospheric_model_optical_depth
    from skytorch.eclipse import stratospheric_aod

    if layer is None:
        return 0.0
    if layer == LOWTRAN_BACKGROUND:
        return stratospheric_model_optical_depth("background")
    return float(np.mean([stratospheric_aod(f"{year}-07-01") for year in STRATOSPHERE_YEARS]))


def atmosphere(profile, ozone_du, layer=None):
    """Return the scenes' turbidity with the ozone tent or an AFGL sounding.

    With ``layer`` the stratospheric sulfate layer of :func:`stratospheric_depth`, in
    LOWTRAN 7's background profile.
    """
    from skytorch.atmosphere import Atmosphere
    from skytorch.atmosphere.climatology import afgl_profile

    options = {} if ozone_du is None else {"ozone_du": ozone_du}
    if layer is not None:
        options.update(stratospheric_aerosol_optical_depth=stratospheric_depth(layer),
                       stratospheric_aerosol_profile="background")
    if profile is None:
        return Atmosphere.earth(turbidity=TURBIDITY, **options)
    return Atmosphere.earth(turbidity=TURBIDITY, profile=afgl_profile(profile), **options)


def sunlit_zenith_v(atm, sun_zenith_deg):
    """V [mag arcsec-2] of the sunlit zenith sky at Paranal's height, every order."""
    import torch

    from skytorch.atmosphere.multiple_scattering import TableResolution, precompute_scattering
    from skytorch.moon.sky import radiance_to_mag_arcsec2
    from skytorch.scene.presets import FIDELITY
    from skytorch.spectrum import solar_irradiance

    wavelength = torch.linspace(470.0, 700.0, 12, dtype=torch.float64)
    tables = precompute_scattering(
        atm, wavelength, scattering_orders="converged",
        resolution=TableResolution(**FIDELITY["default"]["ms_tables"]))
    sun = torch.tensor(np.radians(sun_zenith_deg), dtype=torch.float64)
    zero = torch.zeros_like(sun)
    radiance = tables.radiance(torch.tensor(PARANAL[2], dtype=torch.float64), zero, zero,
                               sun) * solar_irradiance(wavelength)
    return radiance_to_mag_arcsec2(radiance, wavelength).numpy()


def column_du(profile, ozone_du):
    """Ozone column of a case [DU]."""
    from skytorch.atmosphere.climatology import afgl_columns

    return ozone_du if ozone_du is not None else afgl_columns(profile)["ozone_du"]


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    import matplotlib.pyplot as plt

    if arguments.quick:
        cases = (ATMOSPHERES[0], ATMOSPHERES[1], ATMOSPHERES[8])
        sun_zenith = np.array([95.0, 98.0, 101.0])
    else:
        cases, sun_zenith = ATMOSPHERES, np.arange(95.0, 102.5, 1.0)
    labels = [c[0] for c in cases]
    sunlit = np.stack([sunlit_zenith_v(atmosphere(p, o, layer), sun_zenith)
                       for _, p, o, layer in cases])
    # the fit less the night sky: the scattered light of the measurements
    scattered = -2.5 * np.log10(10.0 ** (-0.4 * patat_v(sun_zenith))
                                - 10.0 ** (-0.4 * NIGHT_SKY_V))
    dims = ("atmosphere", "sun_zenith")
    dataset = xr.Dataset(
        {"sunlit_v": (dims, sunlit, {"units": "mag arcsec-2", "long_name": "zenith V of "
                                     "the sunlit sky at 2635 m, every order"}),
         "patat2006_scattered_v": ("sun_zenith", scattered, {
             "units": "mag arcsec-2", "long_name": f"Patat et al. 2006 fit less a "
                                                   f"{NIGHT_SKY_V} V night sky"}),
         "difference": (dims, sunlit - scattered[None], {
             "units": "mag", "long_name": "model minus the measured scattered light "
                                          "(positive: the model is fainter)"}),
         "change": (dims, sunlit - sunlit[:1], {
             "units": "mag", "long_name": "change from the scenes' atmosphere (negative: "
                                          "brighter)"}),
         "ozone_column": ("atmosphere", [column_du(p, o) for _, p, o, _ in cases],
                          {"units": "DU"}),
         "stratospheric_aod": ("atmosphere", [stratospheric_depth(c[3]) for c in cases], {
             "units": "1", "long_name": "vertical optical depth at 550 nm of the "
                                        "stratospheric sulfate layer"}),
         "afgl_profile": ("atmosphere", [p or "tent" for _, p, _, _ in cases])},
        coords={"atmosphere": ("atmosphere", labels),
                "sun_zenith": ("sun_zenith", sun_zenith, {"units": "degree"})},
        attrs={"title": "Zenith twilight at Paranal: ozone column and model atmosphere",
               "site": "ESO-Paranal 24.627 S, 70.404 W, 2635 m",
               "references": "Patat, Ugolnikov & Postylyakov 2006, A&A 455, 385; Patat 2003, "
                             "A&A 400, 1183; Anderson et al. 1986, AFGL-TR-86-0110; Noll et "
                             "al. 2012, A&A 543, A92; Sato et al. 1993, JGR 98, 22987 and "
                             "Thomason et al. 2018, ESSD 10, 469 (stratospheric record); "
                             "Shettle & Fenn 1979, AFGL-TR-79-0214 (LOWTRAN background)"})
    figure, axis = plt.subplots(figsize=(6, 4))
    for i, label in enumerate(labels):
        axis.plot(sun_zenith, sunlit[i] - scattered, "o-", ms=3, label=label)
    axis.axhline(0.0, color="k", lw=0.8)
    axis.set_xlabel("Sun zenith distance [degree]")
    axis.set_ylabel("model − (Patat fit − night sky) [mag]")
    axis.legend(fontsize=7)
    save_outputs(dataset, figure, arguments.output_dir, "twilight_zenith_profiles")
    rows = ["| atmosphere | " + " | ".join(f"{z:.0f}°" for z in sun_zenith) + " |",
            "| --- " * (len(sun_zenith) + 1) + "|",
            "| Patat et al. 2006 less 21.6 V | " + " | ".join(f"{v:.2f}" for v in scattered)
            + " |"]
    for i, label in enumerate(labels):
        rows.append(f"| {label} | " + " | ".join(
            f"{d:+.2f}" for d in sunlit[i] - scattered) + " |")
    print("\n".join(rows))
    return dataset


if __name__ == "__main__":
    main()
