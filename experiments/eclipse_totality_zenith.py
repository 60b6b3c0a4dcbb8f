"""The zenith at totality against measurements: luminance and ratio to the day sky.

For each site, the zenith radiance of the eclipse sky (orders 1 and 2,
:func:`skytorch.scene.solar_eclipse_sky.eclipsed_single_scattering` and
:func:`~skytorch.scene.solar_eclipse_sky.eclipsed_second_order`, quadrature 16/4/16/16;
and every order, with
:func:`skytorch.scene.eclipse_higher_orders.eclipsed_higher_orders` on coarse converged
tables, defaults) at the local maximum (:func:`skytorch.eclipse.solar_eclipse_local`)
and 24 h later, on 7 wavelengths 400–700 nm, turbidity 2, black ground; luminance with
the CIE photopic efficiency. Measured: Lowman, Idaho, 2017-08-21, hand-held SQM overhead 12.7 and
13.1–13.3 mag arcsec⁻² (nightwise.org, "Measuring Darkness During Totality"); day-sky
ratios 3.8e-4 (Quehua 1966, Appl. Opt. 1968) and 1e-4 (Shaw 1975, Appl. Opt. 14, 388).

Output: ``eclipse_totality_zenith.nc`` / ``.png``; ``--quick`` takes Lowman only (a
coarser second order is not a shortcut here: at totality orders 1-2 of the zenith are
nearly all order 2, and 8/2/8/8 misses half of it).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import torch
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import parse_arguments, save_outputs  # noqa: E402

#: name, date, lat, lon, height [m]
SITES = (("Lowman 2017", "2017-08-21", 44.08, -115.62, 1180.0),
         ("Burgos 2026", "2026-08-12", 42.34, -3.70, 850.0))
#: SQM readings at Lowman [mag arcsec-2]: overhead, and the others' range
LOWMAN_SQM = (12.7, 13.1, 13.33)
#: L [cd m-2] = 10.8e4 * 10^(-0.4 m) (Krisciunas & Schaefer 1991 via Falchi et al. 2016)
SQM_TO_CD = 10.8e4


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    import matplotlib.pyplot as plt

    import skytorch as st
    from skytorch.atmosphere.multiple_scattering import TableResolution, precompute_scattering
    from skytorch.atmosphere.tables import TransmittanceTable
    from skytorch.scene.eclipse_higher_orders import eclipsed_higher_orders
    from skytorch.scene.geometry import site_geometries
    from skytorch.scene.solar_eclipse_sky import (
        eclipsed_second_order,
        eclipsed_single_scattering,
    )
    from skytorch.spectrum import photopic_luminous_efficiency, solar_irradiance

    sites = SITES[:1] if arguments.quick else SITES
    quadrature = (16, 4, 16, 16)
    atmosphere = st.Atmosphere.earth(2.0)
    wavelength = torch.linspace(400.0, 700.0, 7, dtype=torch.float64)
    table = TransmittanceTable.build(atmosphere, wavelength, cache=False, n_mu=128, n_r=32)
    tables = precompute_scattering(atmosphere, wavelength, scattering_orders="converged",
                                   resolution=TableResolution(n_r=8, n_mu=32, n_mu_s=16,
                                                              n_phi=6, n_ray=48,
                                                              mu_vertical_weight=0.0,
                                                              r_ground_weight=0.0,
                                                              sphere_phi_refinement=1,
                                                              ray_quadrature="trapezoid"))
    zero = torch.zeros(1, dtype=torch.float64)

    def luminance(radiance):
        spectral = radiance[0] * solar_irradiance(wavelength)
        return float(683.0 * torch.trapezoid(spectral * photopic_luminous_efficiency(wavelength),
                                             wavelength))

    def zenith_luminance(instant, lat, lon, height):
        geometry = site_geometries(instant, [lat], [lon], [height])[0]
        n_view, n_mu, n_phi, n_samples = quadrature
        radiance = (eclipsed_single_scattering(atmosphere, wavelength, zero, zero, geometry,
                                               height, n_samples=48, table=table)
                    + eclipsed_second_order(atmosphere, wavelength, zero, zero, geometry,
                                            height, n_view=n_view, n_mu=n_mu, n_phi=n_phi,
                                            n_samples=n_samples, table=table))
        higher = eclipsed_higher_orders(atmosphere, wavelength, zero, zero, geometry, height,
                                        tables=tables, table=table)
        return luminance(radiance), luminance(radiance + higher), geometry.sun_altitude_deg

    totality, day, altitude, totality_all, day_all = [], [], [], [], []
    for _, date, lat, lon, height in sites:
        local = st.eclipse.solar_eclipse_local(date, lat, lon, height)
        instant = np.datetime64(local.maximum_time.values.reshape(-1)[0], "ns")
        value, every, sun_altitude = zenith_luminance(instant, lat, lon, height)
        totality.append(value)
        totality_all.append(every)
        altitude.append(sun_altitude)
        value, every, _ = zenith_luminance(instant + np.timedelta64(1, "D"), lat, lon, height)
        day.append(value)
        day_all.append(every)
    totality, day = np.array(totality), np.array(day)
    totality_all, day_all = np.array(totality_all), np.array(day_all)
    measured = SQM_TO_CD * 10.0 ** (-0.4 * np.array(LOWMAN_SQM))
    dataset = xr.Dataset(
        {"zenith_luminance_totality": ("site", totality,
                                       {"units": "cd m-2", "long_name": "modelled zenith "
                                        "luminance at the local maximum, orders 1-2"}),
         "zenith_luminance_next_day": ("site", day,
                                       {"units": "cd m-2", "long_name": "modelled zenith "
                                        "luminance 24 h later, orders 1-2"}),
         "zenith_luminance_totality_all_orders": (
             "site", totality_all, {"units": "cd m-2", "long_name": "modelled zenith "
                                    "luminance at the local maximum, every order"}),
         "zenith_luminance_next_day_all_orders": (
             "site", day_all, {"units": "cd m-2", "long_name": "modelled zenith luminance "
                               "24 h later, every order"}),
         "sun_altitude": ("site", np.array(altitude),
                          {"units": "degree", "long_name": "Sun altitude at the maximum"}),
         "lowman_measured_luminance": ("reading", measured,
                                       {"units": "cd m-2", "long_name": "SQM readings at "
                                        "Lowman converted with L = 10.8e4 10^(-0.4 m)"})},
        coords={"site": ("site", [s[0] for s in sites]),
                "reading": ("reading", ["overhead", "other, brightest", "other, faintest"])},
        attrs={"title": "Zenith at totality: model against measurements",
               "second_order_quadrature": "/".join(str(v) for v in quadrature),
               "day_sky_ratios_measured": "Quehua 1966: 3.8e-4; Shaw 1975: 1e-4"})
    figure, axis = plt.subplots(figsize=(5, 3.5))
    x = np.arange(len(sites))
    axis.semilogy(x, totality, "rs", label="skytorch, totality (orders 1-2)")
    axis.semilogy(x, totality_all, "m^", label="skytorch, totality (every order)")
    axis.semilogy(x, day, "bo", label="skytorch, next day")
    axis.semilogy(np.zeros(3), measured, "k_", markersize=14, label="Lowman SQM readings")
    axis.set_xticks(x, [s[0] for s in sites])
    axis.set_ylabel("zenith luminance [cd m-2]")
    axis.legend(fontsize=7)
    save_outputs(dataset, figure, arguments.output_dir, "eclipse_totality_zenith")
    rows = ["| site | Sun altitude | totality, orders 1-2 / every order [cd m-2] | next day "
            "[cd m-2] | ratio |", "| --- | --- | --- | --- | --- |"]
    for i, site in enumerate(sites):
        rows.append(f"| {site[0]} | {altitude[i]:.1f}° | {totality[i]:.3g} / "
                    f"{totality_all[i]:.3g} | {day[i]:.4g} / {day_all[i]:.4g} | "
                    f"{totality[i] / day[i]:.2e} / {totality_all[i] / day_all[i]:.2e} |")
    print("\n".join(rows))
    return dataset


if __name__ == "__main__":
    main()
