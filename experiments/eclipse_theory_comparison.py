"""Comparison of the Earth's shadow with lunar-eclipse theory.

Four parts, each written as netCDF + PNG:

``eclipse_theory_profiles``
    Radial profile of ``I / I_sun`` at the mean lunar distance (R 680, G 550, B 440 nm and
    the V band) for: geometry only; refraction only; + molecular extinction; + ozone
    (300 DU); + typical aerosols (Preetham turbidity 2); + clouds (tops at 8 km on 60 % of
    the limb, an illustrative choice); the stratospheric atmosphere of 2015, the Calbuco
    year (``eclipse_atmosphere("2015-09-28")``: global-mean troposphere, aerosol optical
    depth 0.12 at 550 nm, 300 DU, and the year's stratospheric sulfate layer); the
    molecular, typical and stratospheric cases again with single-scattered light
    (``scattering=True``); and the default shadow of that date, with the limb cloud profile
    (``eclipse_shadow("2015-09-28")``). Reference facts: umbra centre ~1/2400 of sunlight
    for molecules without ozone (Vollmer & Gedzelman 2008, energy 400–700 nm); about 100x
    darker with aerosols, ozone and clouds (same paper); bluish umbra rim from ozone.
``eclipse_theory_ozone``
    Ozone sweep (tent peak density 0, 2, 4, 6, 8 x 1e18 m^-3) -> colour of the umbra.
``eclipse_theory_2015``
    Light curve of 2015-09-28 for the typical and the stratospheric 2015 atmosphere vs the
    reported brightness (Vital 2015: ~50 000x fainter than the full Moon at mid-totality,
    i.e. 11.75 mag; Keen 2016: 33 % dimmer than expected for a clear stratosphere).
``eclipse_theory_mars``
    The Martian shadow at Phobos' and Deimos' distances (Schneegans et al. 2025, Fig. 12
    right), refracted light only and with single-scattered light.

Run: ``python experiments/eclipse_theory_comparison.py [--quick] [--output-dir DIR]``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import parse_arguments, save_outputs  # noqa: E402
from skytorch.constants import (  # noqa: E402
    DEIMOS_SEMI_MAJOR_AXIS_M,
    DOBSON_UNIT_PER_M2,
    MEAN_EARTH_MOON_DISTANCE_M,
    PHOBOS_SEMI_MAJOR_AXIS_M,
)
from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable  # noqa: E402

VG2008_CENTRE = 1.0 / 2400.0  #: Vollmer & Gedzelman 2008, molecules only, no ozone
VG2008_EXTRA_DARKENING = 100.0  #: aerosols, ozone, clouds (same paper)
VITAL2015_DIMMING_MAG = 2.5 * np.log10(5.0e4)  #: 2015-09-28 mid-totality vs full Moon
KEEN2016_DIMMER = 0.33  #: 2015-09-28 dimmer than expected for a clear stratosphere
OZONE_TENT_HALF_WIDTH_M = 15_000.0  #: tent 10–40 km (Bruneton 2017; Schneegans 2025)
RGB = (680.0, 550.0, 440.0)
CLOUD_TOP_M = 8_000.0  #: illustrative cloud tops along the terminator [m]
CLOUD_FRACTION = 0.6  #: illustrative fraction of the limb covered by them

REFERENCES = [
    "Vollmer, M., Gedzelman, S. D. 2008, Simulating irradiance and color of the eclipsed "
    "moon, Appl. Opt. 47, H52, doi:10.1364/AO.47.000H52",
    "Schneegans, S. et al. 2025, Physically Based Real-Time Rendering of Eclipses, Computer "
    "Graphics Forum, doi:10.1111/cgf.70220",
    "Vital, H. C. 2015, Analysis of Observations of the 2015 Sep. 28 Total Lunar Eclipse, "
    "https://www.geocities.ws/lunissolar2003/Analysis_Obs_2015_Sep28.htm",
    "Keen, R. A. 2016, poster at the NOAA ESRL Global Monitoring Annual Conference, reported "
    "in New Scientist 2016-05-25, 'Volcano in Chile dampened lunar eclipse's glory'",
]


def _atmospheres():
    from skytorch.atmosphere import Atmosphere
    from skytorch.eclipse import eclipse_atmosphere

    clean = {"aerosol_optical_depth": 0.0}
    return {
        "molecules": Atmosphere.earth(ozone_du=0.0, **clean),
        "ozone": Atmosphere.earth(ozone_du=300.0, **clean),
        "aerosols": Atmosphere.earth(turbidity=2.0, ozone_du=300.0),
        # global-mean troposphere and ozone, the stratospheric sulfate of 2015 (Calbuco)
        "stratospheric": eclipse_atmosphere("2015-09-28"),
    }


def _v_weights(wavelength: torch.Tensor) -> torch.Tensor:
    from skytorch.spectrum import solar_irradiance, v_band_response

    weight = solar_irradiance(wavelength) * v_band_response(wavelength)
    return weight / weight.sum()


def profiles(quick: bool):
    from skytorch.eclipse import eclipse_shadow
    from skytorch.eclipse.shadow import Shadow
    from skytorch.spectrum import solar_irradiance

    atmospheres = _atmospheres()
    cases = {
        "geometry": Shadow.earth(atmospheres["molecules"], refraction=False, extinction=False),
        "refraction": Shadow.earth(atmospheres["molecules"], extinction=False),
        "molecules": Shadow.earth(atmospheres["molecules"]),
        "ozone": Shadow.earth(atmospheres["ozone"]),
        "aerosols": Shadow.earth(atmospheres["aerosols"]),
        "stratospheric": Shadow.earth(atmospheres["stratospheric"]),
        "clouds": Shadow.earth(atmospheres["aerosols"], cloud_top_altitude_m=CLOUD_TOP_M,
                               cloud_fraction=CLOUD_FRACTION),
        "molecules+scattering": Shadow.earth(atmospheres["molecules"], scattering=True),
        "aerosols+scattering": Shadow.earth(atmospheres["aerosols"], scattering=True),
        "stratospheric+scattering": Shadow.earth(atmospheres["stratospheric"], scattering=True),
        # the per-eclipse default: the same atmosphere with the limb cloud profile
        "eclipse_shadow_2015": eclipse_shadow("2015-09-28"),
    }
    step = 20.0 if quick else 10.0
    wavelength = torch.arange(400.0, 720.0 + 0.5 * step, step, dtype=torch.float64)
    offset = torch.linspace(0.0, 1.0e7, 21 if quick else 201, dtype=torch.float64)
    distance = torch.tensor(MEAN_EARTH_MOON_DISTANCE_M, dtype=torch.float64)
    spectra = torch.stack([case.relative_illuminance(distance, offset, wavelength)
                           for case in cases.values()])  # (case, offset, wl)
    rgb_index = [int(torch.argmin((wavelength - w).abs())) for w in RGB]
    v_band = spectra @ _v_weights(wavelength)
    visible = (wavelength >= 400.0) & (wavelength <= 700.0)
    energy = solar_irradiance(wavelength) * visible
    energy_mean = spectra @ (energy / energy.sum())
    names = list(cases)
    centre_energy = {name: float(energy_mean[i, 0]) for i, name in enumerate(names)}
    summary = {
        "molecules_centre_energy_400_700": centre_energy["molecules"],
        "molecules_centre_over_vg2008": centre_energy["molecules"] / VG2008_CENTRE,
        "darkening_clouds_aerosols_ozone_vs_molecules":
            centre_energy["molecules"] / centre_energy["clouds"],
        "darkening_aerosols_ozone_vs_molecules":
            centre_energy["molecules"] / centre_energy["aerosols"],
        "darkening_eclipse_shadow_2015_vs_molecules":
            centre_energy["molecules"] / centre_energy["eclipse_shadow_2015"],
        "refraction_only_centre": float(v_band[1, 0]),
        "molecules_scattering_centre_energy_400_700": centre_energy["molecules+scattering"],
        "molecules_scattering_centre_over_vg2008":
            centre_energy["molecules+scattering"] / VG2008_CENTRE,
    }
    for name in ("molecules", "aerosols", "stratospheric"):
        index = names.index(name)
        with_light = names.index(f"{name}+scattering")
        for label, k in (("v", None), ("b440", rgb_index[2]), ("r680", rgb_index[0])):
            plain = v_band[index, 0] if k is None else spectra[index, 0, k]
            scattered = v_band[with_light, 0] if k is None else spectra[with_light, 0, k]
            summary[f"scattered_share_centre_{label}_{name}"] = float(
                (scattered - plain) / scattered)
    # ozone rim: blue/green ratio near the umbra edge with and without ozone
    rim = int(torch.argmin((offset - 4.4e6).abs()))
    b, g = rgb_index[2], rgb_index[1]
    summary["rim_blue_over_green_molecules"] = float(spectra[2, rim, b] / spectra[2, rim, g])
    summary["rim_blue_over_green_ozone"] = float(spectra[3, rim, b] / spectra[3, rim, g])
    spec = VariableSpec("1", "relative illuminance", "I / I_sun at the mean lunar distance")
    dataset = build_dataset(
        {"relative_illuminance": variable(("case", "offset", "wavelength"), spectra.numpy(),
                                          spec),
         "v_band": variable(("case", "offset"), v_band.numpy(),
                            VariableSpec("1", "V-band relative illuminance",
                                         "Solar-spectrum x V-passband weighted I / I_sun"))},
        {"case": coordinate("case", np.array(names),
                            VariableSpec("1", "atmosphere case", "model case")),
         "offset": coordinate("offset", offset.numpy(),
                              VariableSpec("m", "distance from the shadow axis",
                                           "at 384 400 km behind the Earth")),
         "wavelength": coordinate("wavelength", wavelength.numpy(),
                                  VariableSpec("nm", "wavelength", "vacuum wavelength"))},
        title="Earth's shadow vs lunar-eclipse theory", references=REFERENCES,
        parameters=summary)
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(2, 2, figsize=(11, 8), sharex=True)
    colours = plt.cm.viridis(np.linspace(0, 0.9, len(names)))
    km = offset.numpy() / 1e3
    styles = ["--" if "+scattering" in name else "-" for name in names]
    panels = [("R 680 nm", spectra[..., rgb_index[0]]), ("G 550 nm", spectra[..., g]),
              ("B 440 nm", spectra[..., b]), ("V band", v_band)]
    for axis, (title, values) in zip(axes.flat, panels, strict=True):
        for i, name in enumerate(names):
            axis.semilogy(km, values[i].clamp_min(1e-12).numpy(), color=colours[i],
                          ls=styles[i], label=name)
        axis.axhline(VG2008_CENTRE, color="r", ls=":", lw=1,
                     label="1/2400 (Vollmer & Gedzelman 2008)")
        axis.set_title(title)
        axis.set_ylim(1e-9, 2)
        axis.grid(alpha=0.3)
    for axis in axes[1]:
        axis.set_xlabel("distance from the shadow axis at 384 400 km [km]")
    for axis in axes[:, 0]:
        axis.set_ylabel("I / I_sun")
    axes[0, 0].legend(fontsize=7)
    figure.tight_layout()
    return dataset, figure, summary


def ozone_sweep(quick: bool):
    from skytorch.atmosphere import Atmosphere
    from skytorch.eclipse.lunar import _colour
    from skytorch.eclipse.shadow import Shadow
    from skytorch.spectrum import solar_irradiance

    peaks = np.array([0.0, 2.0, 4.0, 6.0, 8.0]) * 1e18
    step = 20.0 if quick else 10.0
    wavelength = torch.arange(400.0, 720.0 + 0.5 * step, step, dtype=torch.float64)
    offset = torch.linspace(0.0, 4.6e6, 5 if quick else 24, dtype=torch.float64)
    distance = torch.tensor(MEAN_EARTH_MOON_DISTANCE_M, dtype=torch.float64)
    colours, spectra = [], []
    for peak in peaks:
        du = peak * OZONE_TENT_HALF_WIDTH_M / DOBSON_UNIT_PER_M2
        shadow = Shadow.earth(Atmosphere.earth(turbidity=2.0, ozone_du=du))
        value = shadow.relative_illuminance(distance, offset, wavelength)
        spectra.append(value)
        colours.append(_colour(value * solar_irradiance(wavelength), wavelength))
    spectra = torch.stack(spectra)
    colours = torch.stack(colours)
    dataset = build_dataset(
        {"colour": variable(("ozone_peak", "offset", "channel"), colours.numpy(),
                            VariableSpec("1", "sRGB colour of the shadowed surface",
                                         "constant luminance, brightest channel 1")),
         "relative_illuminance": variable(("ozone_peak", "offset", "wavelength"),
                                          spectra.numpy(),
                                          VariableSpec("1", "relative illuminance",
                                                       "I / I_sun"))},
        {"ozone_peak": coordinate("ozone_peak", peaks,
                                  VariableSpec("m-3", "ozone peak number density",
                                               "peak of the 10–40 km tent")),
         "offset": coordinate("offset", offset.numpy(),
                              VariableSpec("m", "distance from the shadow axis", "")),
         "channel": coordinate("channel", np.array(["R", "G", "B"]),
                               VariableSpec("1", "sRGB channel", "")),
         "wavelength": coordinate("wavelength", wavelength.numpy(),
                                  VariableSpec("nm", "wavelength", "vacuum wavelength"))},
        title="Ozone sweep: colour of the Earth's umbra", references=REFERENCES,
        parameters={"ozone_du": (peaks * OZONE_TENT_HALF_WIDTH_M / DOBSON_UNIT_PER_M2).tolist()})
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(9, 3.5))
    axis.imshow(colours.numpy(), aspect="auto", origin="lower",
                extent=(0, float(offset[-1]) / 1e3, -0.5, len(peaks) - 0.5))
    axis.set_yticks(range(len(peaks)), [f"{p / 1e18:.0f}e18" for p in peaks])
    axis.set_ylabel("ozone peak density [m^-3]")
    axis.set_xlabel("distance from the shadow axis at 384 400 km [km] (umbra)")
    axis.set_title("colour of the umbra (constant luminance) vs ozone")
    figure.tight_layout()
    return dataset, figure


def light_curves(quick: bool):
    from skytorch.eclipse.lunar import lunar_eclipse
    from skytorch.eclipse.shadow import Shadow

    atmospheres = _atmospheres()
    n_times = 25 if quick else 200
    curves = {}
    for name in ("aerosols", "stratospheric"):
        for scattering in (False, True):
            key = f"{name}+scattering" if scattering else name
            curves[key] = lunar_eclipse("2015-09-28", n_times=n_times, n_images=0,
                                        n_disc=6 if quick else 12,
                                        shadow=Shadow.earth(atmospheres[name],
                                                            scattering=scattering))
    v = np.stack([curves[name].v_magnitude.values for name in curves])
    full = float(curves["aerosols"].v_magnitude.values[0])
    greatest = {name: float(c.attrs["parameter_greatest_v_magnitude"])
                for name, c in curves.items()}
    summary = {
        "full_moon_v": full,
        "greatest_v_typical": greatest["aerosols"],
        "greatest_v_stratospheric": greatest["stratospheric"],
        "dimming_typical_mag": greatest["aerosols"] - full,
        "dimming_stratospheric_mag": greatest["stratospheric"] - full,
        "vital2015_dimming_mag": VITAL2015_DIMMING_MAG,
        "stratospheric_over_typical_brightness": 10 ** (-0.4 * (greatest["stratospheric"]
                                                                - greatest["aerosols"])),
        "keen2016_brightness_ratio": 1.0 - KEEN2016_DIMMER,
        "danjon_l_typical": float(curves["aerosols"].attrs["parameter_danjon_l"]),
        "danjon_l_stratospheric": float(curves["stratospheric"].attrs["parameter_danjon_l"]),
    }
    for name in ("aerosols", "stratospheric"):
        for key in (name, f"{name}+scattering"):
            curve = curves[key]
            middle = int(np.argmax(curve.v_magnitude.values))
            summary[f"greatest_b_minus_v_{key}"] = float(curve.b_magnitude.values[middle]
                                                         - curve.v_magnitude.values[middle])
    summary["greatest_v_typical_scattering"] = greatest["aerosols+scattering"]
    summary["greatest_v_stratospheric_scattering"] = greatest["stratospheric+scattering"]
    summary["stratospheric_over_typical_brightness_scattering"] = 10 ** (
        -0.4 * (greatest["stratospheric+scattering"] - greatest["aerosols+scattering"]))
    times = curves["aerosols"].time.values
    dataset = build_dataset(
        {"v_magnitude": variable(("case", "time"), v,
                                 VariableSpec("mag", "V magnitude of the Moon", "above the "
                                              "atmosphere"))},
        {"case": coordinate("case", np.array(list(curves)),
                            VariableSpec("1", "atmosphere case", "")),
         "time": coordinate("time", times, VariableSpec("", "time", "UTC"))},
        title="2015-09-28 lunar eclipse light curve", references=REFERENCES,
        parameters=summary)
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(8, 4.5))
    hours = (times - times[0]) / np.timedelta64(1, "h")
    for row, name in zip(v, curves, strict=True):
        axis.plot(hours, row, label=f"{name} (greatest V {greatest[name]:.2f})")
    axis.axhline(full + VITAL2015_DIMMING_MAG, color="r", ls=":",
                 label="reported: full Moon + 11.75 mag (Vital 2015)")
    axis.invert_yaxis()
    axis.set_xlabel(f"hours since {np.datetime_as_string(times[0], unit='m')} UTC")
    axis.set_ylabel("V magnitude")
    axis.legend(fontsize=8)
    axis.grid(alpha=0.3)
    figure.tight_layout()
    return dataset, figure, summary


def mars(quick: bool):
    from skytorch.eclipse.shadow import Shadow
    from skytorch.eclipse.shadow_table import shadow_uv_inverse

    shadows = {"refraction": Shadow.mars(), "scattering": Shadow.mars(scattering=True)}
    shadow = shadows["scattering"]
    wavelength = torch.tensor(RGB, dtype=torch.float64)
    n = 21 if quick else 201
    # the penumbra is a thin shell (phi_occ >> phi_sun near Mars): sample it densely
    v = torch.cat([torch.linspace(0.0, 0.9, 10, dtype=torch.float64)[:-1],
                   torch.linspace(0.9, 1.0, n, dtype=torch.float64)])
    n = v.shape[0]
    rows, offsets = [], []
    for distance in (PHOBOS_SEMI_MAJOR_AXIS_M, DEIMOS_SEMI_MAJOR_AXIS_M):
        from skytorch.eclipse.shadow import shadow_angles

        axis_angles = shadow_angles(torch.tensor(distance, dtype=torch.float64),
                                    torch.tensor(0.0, dtype=torch.float64),
                                    shadow.sun_distance_m, shadow.sun_radius_m,
                                    shadow.top_radius_m)
        u = axis_angles["sun_radius_rad"] / (axis_angles["sun_radius_rad"]
                                             + axis_angles["occluder_radius_rad"])
        position = shadow_uv_inverse(u.expand(n), v, shadow.sun_distance_m,
                                     shadow.sun_radius_m, shadow.top_radius_m)
        rows.append(torch.stack([case.relative_illuminance(
            position["distance_m"], position["offset_m"], wavelength)
            for case in shadows.values()]))
        offsets.append(position["offset_m"])
    values = torch.stack(rows)  # (moon, case, v, wavelength)
    summary = {}
    for m, name in enumerate(("phobos", "deimos")):
        for k, w in enumerate(RGB):
            summary[f"mars_{name}_centre_{w:.0f}nm_scattering"] = float(values[m, 1, 0, k])
            summary[f"mars_{name}_centre_{w:.0f}nm_refraction"] = float(values[m, 0, 0, k])
        summary[f"mars_{name}_centre_red_over_blue"] = float(values[m, 1, 0, 0]
                                                             / values[m, 1, 0, 2])
        half = int(torch.argmin((v - 0.5).abs()))
        summary[f"mars_{name}_v05_red_over_blue"] = float(values[m, 1, half, 0]
                                                          / values[m, 1, half, 2])
        summary[f"mars_{name}_v05_{RGB[1]:.0f}nm_scattering"] = float(values[m, 1, half, 1])
    dataset = build_dataset(
        {"relative_illuminance": variable(("moon", "case", "v", "wavelength"), values.numpy(),
                                          VariableSpec("1", "relative illuminance",
                                                       "I / I_sun")),
         "offset": variable(("moon", "v"), torch.stack(offsets).numpy(),
                            VariableSpec("m", "distance from the shadow axis", ""))},
        {"moon": coordinate("moon", np.array(["Phobos", "Deimos"]),
                            VariableSpec("1", "Martian moon", "orbit radius")),
         "case": coordinate("case", np.array(list(shadows)),
                            VariableSpec("1", "light in the shadow", "refracted only, or "
                                         "refracted + single-scattered")),
         "v": coordinate("v", v.numpy(), VariableSpec("1", "shadow coordinate v",
                                                      "0 on the axis, 1 at the penumbra edge")),
         "wavelength": coordinate("wavelength", wavelength.numpy(),
                                  VariableSpec("nm", "wavelength", ""))},
        title="Shadow of Mars at Phobos and Deimos", references=REFERENCES,
        parameters={**shadow.parameters_dict(), **summary})
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for axis, name, row, offset in zip(axes, ("Phobos", "Deimos"), values, offsets,
                                       strict=True):
        for k, colour in enumerate("rgb"):
            axis.semilogy(offset.numpy() / 1e3, row[0, :, k].clamp_min(1e-12).numpy(),
                          color=colour, ls=":", label=f"{RGB[k]:.0f} nm, refracted")
            axis.semilogy(offset.numpy() / 1e3, row[1, :, k].clamp_min(1e-12).numpy(),
                          color=colour, label=f"{RGB[k]:.0f} nm, + scattered")
        axis.set_title(f"Mars' shadow at {name}")
        axis.set_xlabel("distance from the shadow axis [km]")
        axis.set_ylim(1e-11, 2)
        axis.grid(alpha=0.3)
    axes[0].set_ylabel("I / I_sun")
    axes[0].legend(fontsize=7)
    figure.tight_layout()
    return dataset, figure, summary


def limb_views(quick: bool):
    """Return the atmosphere ring seen from the Moon: umbra centre, mid-umbra, umbra edge."""
    from skytorch.eclipse.lunar import _display
    from skytorch.eclipse.shadow import Shadow
    from skytorch.spectrum import solar_irradiance, spectrum_to_xyz

    shadow = Shadow.earth(_atmospheres()["aerosols"], scattering=True)
    step = 40.0 if quick else 20.0
    wavelength = torch.arange(400.0, 720.0 + 0.5 * step, step, dtype=torch.float64)
    offset = torch.tensor([0.0, 2.5e6, 4.4e6], dtype=torch.float64)
    view = shadow.limb_view(torch.tensor(MEAN_EARTH_MOON_DISTANCE_M, dtype=torch.float64),
                            offset, wavelength, n_azimuth=90 if quick else 360,
                            n_altitude=8 if quick else 32, oversample=4 if quick else 8)
    solar = solar_irradiance(wavelength)
    images = _display(spectrum_to_xyz(view["radiance"] * solar, wavelength), 3)
    scattered = _display(spectrum_to_xyz(view["scattered_radiance"] * solar, wavelength), 3)
    dims = ("offset", "altitude", "azimuth", "wavelength")
    dataset = build_dataset(
        {"radiance": variable(dims, view["radiance"].numpy(),
                              VariableSpec("1", "relative radiance of the limb",
                                           "radiance / radiance at the centre of the Sun; "
                                           "refracted and single-scattered light")),
         "scattered_radiance": variable(dims, view["scattered_radiance"].numpy(),
                                        VariableSpec("1", "relative scattered radiance",
                                                     "single-scattered part of radiance")),
         "image": variable(("offset", "altitude", "azimuth", "channel"), images.numpy(),
                           VariableSpec("1", "sRGB", "common exposure per view")),
         "scattered_image": variable(("offset", "altitude", "azimuth", "channel"),
                                     scattered.numpy(),
                                     VariableSpec("1", "sRGB", "scattered light alone, "
                                                  "its own exposure per view"))},
        {"offset": coordinate("offset", offset.numpy(),
                              VariableSpec("m", "distance from the shadow axis", "")),
         "altitude": coordinate("altitude", view["altitude_m"].numpy(),
                                VariableSpec("m", "impact altitude", "bin centre")),
         "azimuth": coordinate("azimuth", np.degrees(view["azimuth_rad"].numpy()),
                               VariableSpec("degree", "ring azimuth", "0 towards the Sun")),
         "wavelength": coordinate("wavelength", wavelength.numpy(),
                                  VariableSpec("nm", "wavelength", "")),
         "channel": coordinate("channel", np.array(["R", "G", "B"]),
                               VariableSpec("1", "sRGB channel", ""))},
        title="Limb of the Earth seen from the eclipsed Moon", references=REFERENCES,
        parameters=shadow.parameters_dict())
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(3, 2, figsize=(14, 5.5))
    top = float(view["altitude_m"][-1]) / 1e3
    for row, km in enumerate(offset.numpy() / 1e3):
        for axis, image, what in ((axes[row, 0], images[row], "refracted + scattered"),
                                  (axes[row, 1], scattered[row], "scattered alone")):
            axis.imshow(image.numpy(), aspect="auto", origin="lower",
                        extent=(-180, 180, 0, top))
            axis.set_ylabel("impact alt. [km]")
            axis.set_title(f"{what}, seen from {km:.0f} km off the shadow axis "
                           "(exposure per view)", fontsize=8)
    for axis in axes[-1]:
        axis.set_xlabel("ring azimuth from the Sun's direction [degree]")
    flux = view["scattered_radiance"] * view["solid_angle_sr"][..., None]
    high = flux[:, view["altitude_m"] > 20e3].sum((1, 2))  # (offset, wavelength)
    blue, red = int(torch.argmin((wavelength - 440.0).abs())), int(
        torch.argmin((wavelength - 680.0).abs()))
    summary = {f"limb_scattered_above_20km_440_over_680_at_{km:.0f}km":
               float(high[i, blue] / high[i, red]) for i, km in enumerate(offset / 1e3)}
    figure.tight_layout()
    return dataset, figure, summary


def main(argv=None) -> int:
    args = parse_arguments(__doc__.splitlines()[0], argv)
    for build, stem in ((profiles, "profiles"), (ozone_sweep, "ozone"),
                        (light_curves, "2015"), (mars, "mars"), (limb_views, "limb")):
        dataset, figure, *summary = build(args.quick)
        save_outputs(dataset, figure, args.output_dir, f"eclipse_theory_{stem}")
        for key, value in (summary[0] if summary else {}).items():
            print(f"{key}: {value:.6g}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
