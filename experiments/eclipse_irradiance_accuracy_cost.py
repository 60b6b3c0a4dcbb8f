"""Accuracy versus cost of the horizontal irradiance during a partial solar eclipse.

Wettermast Hamburg (53.519 N, 10.103 E, 10 m) at its maximum of 2015-03-20 (09:44:47 UTC,
obscuration 0.79, Sun 32° up), turbidity 2, 450/650/850 nm:
:func:`skytorch.scene.eclipse_irradiance.eclipsed_horizontal_irradiance` with and without
the Moon for hemisphere quadratures ``(n_mu, n_phi, n_samples)`` and second-order
quadratures ``(n_view, n_mu, n_phi, n_samples)`` (or none) from coarse to fine, against
the finest; the global ratio (eclipse over clear, band integral), the clear diffuse
irradiance and the wall time of each (both skies, one thread).

Second part: the stations that recorded the eclipse under a clear sky (Hamburg, Leipzig,
Belgrade), the modelled global ratio at each maximum (default quadrature, 350–1050 nm)
against the recorded one and against the uniform disc's ``1 - obscuration``.

Output: ``eclipse_irradiance_accuracy_cost.nc`` / ``.png``; ``--quick`` drops the two
finest quadratures and Belgrade.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import torch
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import parse_arguments, save_outputs  # noqa: E402

HAMBURG = (53.519, 10.103, 10.0)
#: (n_mu, n_phi, n_samples, second order); the module's default is the fifth
QUADRATURES = ((2, 4, 8, None), (4, 8, 24, None), (6, 16, 48, None),
               (4, 8, 24, (8, 2, 8, 8)), (6, 16, 48, (12, 4, 12, 12)),
               (8, 24, 64, (16, 4, 16, 16)), (10, 32, 96, (24, 6, 24, 24)))
#: site, lat, lon, height [m], recorded ratio, source
STATIONS = (("Hamburg", 53.519, 10.103, 10.0, 92.0 / 565.0,
             "wettermast.uni-hamburg.de, SoFi20150320: 92 of 565 W m-2 (cloudless course)"),
            ("Leipzig", 51.353, 12.435, 125.0, 150.0 / 600.0,
             "tropos.de, Sonnenfinsternis 2015: ca. 600 to ca. 150 W m-2"),
            ("Belgrade", 44.82, 20.46, 130.0, 0.52,
             "Ilic et al. 2018, JASTP 171, 250: global radiation down 48 %"))


def _label(quadrature):
    n_mu, n_phi, n_samples, second = quadrature
    orders = "1" if second is None else "1-2 " + "/".join(str(v) for v in second)
    return f"{n_mu}x{n_phi}x{n_samples}, orders {orders}"


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    import matplotlib.pyplot as plt

    import skytorch as st
    from skytorch.atmosphere.tables import TransmittanceTable
    from skytorch.scene.eclipse_irradiance import (
        eclipsed_horizontal_irradiance,
        solar_eclipse_irradiance,
    )
    from skytorch.scene.geometry import site_geometries
    from skytorch.spectrum import solar_irradiance

    torch.set_num_threads(1)
    quadratures = QUADRATURES[:-2] if arguments.quick else QUADRATURES
    atmosphere = st.Atmosphere.earth(2.0)
    wavelength = torch.tensor([450.0, 650.0, 850.0], dtype=torch.float64)
    spectrum = solar_irradiance(wavelength)
    table = TransmittanceTable.build(atmosphere, wavelength, cache=False, n_mu=128, n_r=32)
    local = st.eclipse.solar_eclipse_local("2015-03-20", *HAMBURG)
    maximum = np.datetime64(local.maximum_time.values.reshape(-1)[0], "ns")
    geometry = site_geometries(maximum, [HAMBURG[0]], [HAMBURG[1]], [HAMBURG[2]])[0]

    def band(irradiance):
        return float(torch.trapezoid(irradiance * spectrum, wavelength))

    # one untimed evaluation first (the first call of each kernel pays its set-up)
    eclipsed_horizontal_irradiance(atmosphere, wavelength, geometry, HAMBURG[2], n_mu=1,
                                   n_phi=1, n_samples=2, second_order=(2, 1, 1, 2),
                                   table=table)
    ratios, diffuse, seconds = [], [], []
    for n_mu, n_phi, n_samples, second in quadratures:
        options = {"n_mu": n_mu, "n_phi": n_phi, "n_samples": n_samples,
                   "second_order": second, "table": table}
        start = time.perf_counter()
        eclipsed = eclipsed_horizontal_irradiance(atmosphere, wavelength, geometry,
                                                  HAMBURG[2], **options)
        clear = eclipsed_horizontal_irradiance(atmosphere, wavelength, geometry, HAMBURG[2],
                                               moon=False, **options)
        seconds.append(time.perf_counter() - start)
        ratios.append(band(eclipsed.global_) / band(clear.global_))
        diffuse.append(band(clear.diffuse))
    ratios, diffuse = np.array(ratios), np.array(diffuse)
    labels = [_label(q) for q in quadratures]
    stations = STATIONS[:2] if arguments.quick else STATIONS
    modelled, obscuration = [], []
    for _, lat, lon, height, _, _ in stations:
        circumstances = st.eclipse.solar_eclipse_local("2015-03-20", lat, lon, height)
        instant = np.datetime64(circumstances.maximum_time.values.reshape(-1)[0], "ns")
        obscuration.append(float(circumstances.obscuration.values.reshape(-1)[0]))
        modelled.append(float(solar_eclipse_irradiance(instant, lat, lon, height).global_ratio))
    dataset = xr.Dataset(
        {"global_ratio": ("quadrature", ratios,
                          {"units": "1", "long_name": "global irradiance during the eclipse "
                                                      "over the clear value, 450-850 nm"}),
         "diffuse_clear": ("quadrature", diffuse,
                           {"units": "W m-2", "long_name": "clear-sky diffuse irradiance, "
                                                           "450-850 nm, orders 1-2"}),
         "seconds": ("quadrature", np.array(seconds),
                     {"units": "s", "long_name": "wall time, eclipse and clear skies"}),
         "station_modelled_ratio": ("station", np.array(modelled),
                                    {"units": "1", "long_name": "modelled global ratio at "
                                                                "maximum, 350-1050 nm"}),
         "station_recorded_ratio": ("station", np.array([s[4] for s in stations]),
                                    {"units": "1", "long_name": "recorded global ratio"}),
         "station_obscuration": ("station", np.array(obscuration),
                                 {"units": "1", "long_name": "obscuration at maximum"})},
        coords={"quadrature": ("quadrature", labels,
                               {"long_name": "n_mu x n_phi x n_samples, orders"}),
                "station": ("station", [s[0] for s in stations])},
        attrs={"title": "Horizontal irradiance during a partial solar eclipse: accuracy "
                        "vs cost", "scene": f"Hamburg {HAMBURG}, {maximum} UTC, turbidity 2",
               "reference": labels[-1],
               "sources": "; ".join(f"{s[0]}: {s[5]}" for s in stations)})
    figure, (left, right) = plt.subplots(1, 2, figsize=(9, 3.5))
    error = np.maximum(np.abs(ratios[:-1] - ratios[-1]), 1e-6)
    left.loglog(seconds[:-1], error, "o-", label="global ratio (absolute)")
    left.loglog(seconds[:-1], np.maximum(np.abs(diffuse[:-1] / diffuse[-1] - 1.0), 1e-6),
                "s-", label="clear diffuse (relative)")
    left.set_xlabel("time, eclipse and clear skies, 3 wavelengths [s]")
    left.set_ylabel(f"difference from {labels[-1]}")
    left.legend(fontsize=7)
    x = np.arange(len(stations))
    right.plot(x, [s[4] for s in stations], "ko", label="recorded")
    right.plot(x, modelled, "rs", label="skytorch (limb-darkened Sun, sky orders 1-2)")
    right.plot(x, 1.0 - np.array(obscuration), "b^", label="1 - obscuration (uniform disc)")
    right.set_xticks(x, [s[0] for s in stations])
    right.set_ylabel("global irradiance, eclipse / clear")
    right.set_title("2015-03-20 at maximum")
    right.legend(fontsize=7)
    save_outputs(dataset, figure, arguments.output_dir, "eclipse_irradiance_accuracy_cost")
    rows = ["| quadrature | global ratio | difference | clear diffuse [W m-2] | time [s] |",
            "| --- | --- | --- | --- | --- |"]
    for i, label in enumerate(labels):
        rows.append(f"| {label} | {ratios[i]:.4f} | {ratios[i] - ratios[-1]:+.4f} | "
                    f"{diffuse[i]:.2f} | {seconds[i]:.2f} |")
    rows += ["", "| station | obscuration | 1 - obscuration | modelled | recorded |",
             "| --- | --- | --- | --- | --- |"]
    for i, station in enumerate(stations):
        rows.append(f"| {station[0]} | {obscuration[i]:.3f} | {1 - obscuration[i]:.3f} | "
                    f"{modelled[i]:.3f} | {station[4]:.3f} |")
    print("\n".join(rows))
    return dataset


if __name__ == "__main__":
    main()
