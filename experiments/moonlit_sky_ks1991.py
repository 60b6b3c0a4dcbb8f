"""The moonlit sky against Krisciunas & Schaefer (1991) at the site and extinction of their data.

Krisciunas & Schaefer (1991, PASP 103, 1033, doi:10.1086/132921) fitted their moonlit-sky
model (eq. 15–21) to V sky brightnesses measured from the 2800 m level of Mauna Kea, with a
V extinction coefficient k = 0.172 mag per air mass, and give its accuracy as 8–23 %. Its
scattering function f(ρ) = 10^5.36 [1.06 + cos² ρ] + 10^(6.15 − ρ/40) is fitted for ρ ≳ 10°
and depends on the aerosol only through k. Compared at sea level with other extinctions
(docs/moon.md, "Multiple scattering of moonlight") the model is an extrapolation; here the
comparison is made where it was fitted.

The model: an observer at 2800 m, the atmosphere's aerosol optical depth chosen so that its
zenith extinction at 550 nm from 2800 m is K&S's 0.172 mag (300 DU of ozone), for three
aerosols: the default (Ångström law, single-scattering albedo 0.9, Cornette–Shanks phase
function of asymmetry 0.8: Bruneton's 2017 demo aerosol) and the OPAC continental-average
and clean-maritime types (Mie tables, Henyey–Greenstein with their asymmetry per
wavelength). The Moon at zenith 30° and 60°, phase angles 10°, 45°, 90°, views along the
vertical through the Moon and the zenith at separations ρ from 10° to 120° (zenith
distance of the view up to 85°). The sky's V surface brightness from the single scattering
(:func:`skytorch.moon.sky.moonlit_sky_single_scattering`, 470–700 nm every 5 nm) and with
every order (:func:`skytorch.moon.sky.moonlit_sky_multiple_scattering` on the scenes'
default tables, converged orders, at 6 wavelength nodes whose ratio to the single
scattering is interpolated onto the fine grid, as the scenes do). K&S is evaluated with
its own Moon (eq. 20) and, to separate the sky's scattering from the Moon's brightness,
with skytorch's Moon (:func:`skytorch.moon.brightness.magnitude`, 0.11–0.13 mag fainter
than K&S's eq. 9 at these phase angles). Nothing is fitted.

Output: ``moonlit_sky_ks1991.nc`` / ``.png``; ``--quick`` runs the default aerosol only.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import parse_arguments, save_outputs  # noqa: E402

#: K&S's observing site on Mauna Kea [m]
SITE_M = 2800.0
#: the aerosols compared: (label, ``aerosol_type`` of ``Atmosphere.earth``)
AEROSOLS = (("default", None), ("continental_average", "continental_average"),
            ("maritime_clean", "maritime_clean"))
MOON_ZENITH_DEG = (30.0, 60.0)
PHASE_ANGLE_DEG = (10.0, 45.0, 90.0)
SEPARATION_DEG = (10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 90.0, 120.0)
#: views closer to the horizon than this are left out [degree]
MAX_VIEW_ZENITH_DEG = 85.0
OZONE_DU = 300.0
#: K&S's accuracy, 23 % at most, in magnitudes
KS1991_ACCURACY_MAG = 2.5 * math.log10(1.23)


def atmosphere_with_extinction(aerosol_type, extinction_mag: float, altitude_m: float):
    """Return the atmosphere whose zenith extinction at 550 nm from ``altitude_m`` is k.

    The aerosol optical depth (at sea level, 550 nm) is the root of k(τ) − k by Brent's
    method; ``aerosol_type`` None is the default aerosol.
    """
    from scipy.optimize import brentq

    from skytorch.atmosphere import Atmosphere
    from skytorch.moon.sky import extinction_coefficient_v

    options = {} if aerosol_type is None else {"aerosol_type": aerosol_type}

    def build(tau):
        return Atmosphere.earth(aerosol_optical_depth=tau, ozone_du=OZONE_DU, **options)

    def excess(tau):
        return float(extinction_coefficient_v(build(tau), 550.0, altitude_m=altitude_m)) \
            - extinction_mag

    if excess(0.0) >= 0.0:
        raise ValueError(f"the molecules and ozone alone already give k = "
                         f"{excess(0.0) + extinction_mag:.3f} mag at {altitude_m} m")
    return build(brentq(excess, 0.0, 5.0, xtol=1e-12))


def geometry():
    """(moon zenith, phase angle, separation) grid: view zenith and azimuth from the Moon.

    Views along the vertical through the Moon: towards the zenith (azimuth 0) while ρ ≤ Z_m,
    beyond it (azimuth 180°) after; NaN where the view is below ``MAX_VIEW_ZENITH_DEG``.
    """
    zm, _, rho = np.meshgrid(MOON_ZENITH_DEG, PHASE_ANGLE_DEG, SEPARATION_DEG, indexing="ij")
    zenith = np.abs(zm - rho)
    azimuth = np.where(rho <= zm, 0.0, 180.0)
    zenith = np.where(zenith <= MAX_VIEW_ZENITH_DEG, zenith, np.nan)
    return zenith, azimuth


def sky_v(atmosphere, view_zenith_deg, view_azimuth_deg):
    """V [mag arcsec-2] of the single-scattered and of the whole moonlit sky on the grid.

    Returns (single, multiple, orders computed), each of the grid's shape (NaN where the
    view is left out).
    """
    import torch

    from skytorch.atmosphere.multiple_scattering import TableResolution, precompute_scattering
    from skytorch.moon import sky
    from skytorch.scene.presets import FIDELITY

    fine = torch.arange(470.0, 701.0, 5.0, dtype=torch.float64)
    nodes = torch.linspace(470.0, 700.0, 6, dtype=torch.float64)
    tables = precompute_scattering(
        atmosphere, nodes, scattering_orders="converged",
        resolution=TableResolution(**FIDELITY["default"]["ms_tables"]))
    shape = view_zenith_deg.shape
    zm, alpha, _ = (a.reshape(-1) for a in np.meshgrid(
        MOON_ZENITH_DEG, PHASE_ANGLE_DEG, SEPARATION_DEG, indexing="ij"))
    keep = np.isfinite(view_zenith_deg.reshape(-1))

    def radians(values):
        return torch.tensor(np.radians(values[keep]), dtype=torch.float64)

    args = (atmosphere, radians(alpha), radians(zm), radians(view_zenith_deg.reshape(-1)),
            radians(view_azimuth_deg.reshape(-1)))
    single = sky.moonlit_sky_single_scattering(*args, fine, altitude_m=SITE_M)
    ratio = (sky.moonlit_sky_multiple_scattering(atmosphere, tables, *args[1:],
                                                 altitude_m=SITE_M)
             / sky.moonlit_sky_single_scattering(*args, nodes, altitude_m=SITE_M))
    ratio = torch.from_numpy(np.stack([np.interp(fine.numpy(), nodes.numpy(), row)
                                       for row in ratio.numpy()]))
    out = []
    for radiance in (single, single * ratio):
        v = np.full(keep.shape, np.nan)
        v[keep] = sky.radiance_to_mag_arcsec2(radiance, fine).numpy()
        out.append(v.reshape(shape))
    return out[0], out[1], tables.orders_computed


def ks1991_v(view_zenith_deg, moon_offset_mag):
    """K&S's moonlit sky [mag arcsec-2] on the grid, its Moon made fainter by an offset.

    ``moon_offset_mag`` (phase angle,) is added to K&S's lunar magnitude (0: their eq. 20).
    """
    import torch

    from skytorch.moon import sky
    from skytorch.moon.sky import KS1991_EXTINCTION_MAG

    zm, alpha, rho = np.meshgrid(MOON_ZENITH_DEG, PHASE_ANGLE_DEG, SEPARATION_DEG,
                                 indexing="ij")
    keep = np.isfinite(view_zenith_deg)

    def radians(values):
        return torch.tensor(np.radians(values[keep]), dtype=torch.float64)

    nl = sky.moonlit_sky_ks1991(radians(alpha), radians(rho), radians(zm),
                                radians(view_zenith_deg), KS1991_EXTINCTION_MAG)
    v = np.full(view_zenith_deg.shape, np.nan)
    offset = np.broadcast_to(np.reshape(moon_offset_mag, (1, -1, 1)), v.shape)
    v[keep] = sky.nanolambert_to_mag_arcsec2(nl).numpy() + offset[keep]
    return v


def moon_offset():
    """Return the lunar V of skytorch minus K&S's eq. 9 at the phase angles [mag]."""
    import torch

    from skytorch.moon.brightness import magnitude, magnitude_ks1991

    alpha = torch.tensor(np.radians(PHASE_ANGLE_DEG), dtype=torch.float64)
    return (magnitude(alpha) - magnitude_ks1991(alpha)).numpy()


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    import matplotlib.pyplot as plt

    from skytorch.moon.sky import KS1991_EXTINCTION_MAG, extinction_coefficient_v

    aerosols = AEROSOLS[:1] if arguments.quick else AEROSOLS
    zenith, azimuth = geometry()
    offset = moon_offset()
    ks = ks1991_v(zenith, np.zeros(len(PHASE_ANGLE_DEG)))
    ks_moon = ks1991_v(zenith, offset)
    single, multiple, depth, k, orders = [], [], [], [], []
    from skytorch.atmosphere import Atmosphere

    molecules = float(extinction_coefficient_v(
        Atmosphere.earth(aerosol_optical_depth=0.0, ozone_du=OZONE_DU), 550.0,
        altitude_m=SITE_M))
    for _, aerosol_type in aerosols:
        atmosphere = atmosphere_with_extinction(aerosol_type, KS1991_EXTINCTION_MAG, SITE_M)
        s, m, n = sky_v(atmosphere, zenith, azimuth)
        single.append(s)
        multiple.append(m)
        orders.append(n)
        k.append(float(extinction_coefficient_v(atmosphere, 550.0, altitude_m=SITE_M)))
        # the aerosol's share of the extinction, as an optical depth
        depth.append((k[-1] - molecules) * math.log(10.0) / 2.5)
    single, multiple = np.stack(single), np.stack(multiple)
    labels = [a[0] for a in aerosols]
    grid = ("moon_zenith", "phase_angle", "separation")
    dims = ("aerosol",) + grid
    mag = {"units": "mag arcsec-2"}
    dataset = xr.Dataset(
        {"v_single": (dims, single, {**mag, "long_name": "V of the single-scattered "
                                     "moonlit sky"}),
         "v_multiple": (dims, multiple, {**mag, "long_name": "V of the moonlit sky, every "
                                         "order of scattering"}),
         "v_ks1991": (grid, ks, {**mag, "long_name": "Krisciunas & Schaefer 1991, eq. 15-21, "
                                 "k = 0.172"}),
         "v_ks1991_skytorch_moon": (grid, ks_moon, {
             **mag, "long_name": "Krisciunas & Schaefer 1991 with skytorch's lunar V"}),
         "difference": (dims, multiple - ks[None], {
             "units": "mag", "long_name": "every order minus K&S (positive: skytorch is "
                                          "fainter)"}),
         "difference_skytorch_moon": (dims, multiple - ks_moon[None], {
             "units": "mag", "long_name": "every order minus K&S with skytorch's Moon"}),
         "view_zenith": (grid, zenith, {"units": "degree"}),
         "view_azimuth_from_moon": (grid, azimuth, {"units": "degree"}),
         "moon_offset": ("phase_angle", offset, {
             "units": "mag", "long_name": "skytorch's lunar V minus K&S eq. 9"}),
         "extinction_550": ("aerosol", k, {"units": "mag", "long_name": "zenith extinction "
                                           "at 550 nm from the site"}),
         "aerosol_optical_depth_550": ("aerosol", depth, {
             "units": "1", "long_name": "aerosol optical depth above the site at 550 nm"}),
         "orders_computed": ("aerosol", orders)},
        coords={"aerosol": ("aerosol", labels),
                "moon_zenith": ("moon_zenith", list(MOON_ZENITH_DEG), {"units": "degree"}),
                "phase_angle": ("phase_angle", list(PHASE_ANGLE_DEG), {"units": "degree"}),
                "separation": ("separation", list(SEPARATION_DEG), {"units": "degree"})},
        attrs={"title": "Moonlit sky at Mauna Kea 2800 m, k = 0.172: skytorch against "
                        "Krisciunas & Schaefer 1991",
               "references": "Krisciunas & Schaefer 1991, PASP 103, 1033, "
                             "doi:10.1086/132921"})
    figure, axes = plt.subplots(1, len(labels), figsize=(4.2 * len(labels), 3.6),
                                sharey=True, squeeze=False)
    for a, label in enumerate(labels):
        axis = axes[0, a]
        for i, zm in enumerate(MOON_ZENITH_DEG):
            for j, alpha in enumerate(PHASE_ANGLE_DEG):
                axis.plot(SEPARATION_DEG, multiple[a, i, j] - ks[i, j], "o-" if i else "s--",
                          ms=3, label=f"Z$_m$ {zm:.0f}°, α {alpha:.0f}°")
        axis.axhspan(-KS1991_ACCURACY_MAG, KS1991_ACCURACY_MAG, color="0.9")
        axis.axhline(0.0, color="k", lw=0.8)
        axis.set_title(f"aerosol: {label}", fontsize=9)
        axis.set_xlabel("separation from the Moon ρ [degree]")
    axes[0, 0].set_ylabel("skytorch − K&S 1991 [mag]")
    axes[0, 0].legend(fontsize=6)
    save_outputs(dataset, figure, arguments.output_dir, "moonlit_sky_ks1991")
    rows = ["| aerosol (τ550 above 2800 m, orders) | " + " | ".join(
        f"ρ {r:.0f}°" for r in SEPARATION_DEG) + " | all: mean / rms | within 23 % |",
        "| --- " * (len(SEPARATION_DEG) + 3) + "|"]
    for a, label in enumerate(labels):
        for name, diff in (("", multiple[a] - ks), (", K&S with skytorch's Moon",
                                                     multiple[a] - ks_moon)):
            per_rho = np.nanmean(diff, axis=(0, 1))
            values = diff[np.isfinite(diff)]
            cells = " | ".join(f"{v:+.2f}" for v in per_rho)
            rows.append(f"| {label}{name} ({depth[a]:.3f}, {orders[a]}) | {cells} | "
                        f"{values.mean():+.2f} / {np.sqrt((values ** 2).mean()):.2f} | "
                        f"{int((np.abs(values) <= KS1991_ACCURACY_MAG).sum())}/{values.size} |")
    print("\n".join(rows))
    return dataset


if __name__ == "__main__":
    main()
