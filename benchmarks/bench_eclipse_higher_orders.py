"""Benchmark of the eclipse sky's orders >= 3 against its orders 1 and 2, at totality.

Workload: the totality of 2026-08-12 at Burgos (Sun 8° high), ``Atmosphere.earth(turbidity=2)``
at 3 wavelengths (450, 550, 650 nm), coarse converged tables (8 × 32 × 16 × 6); 7 lines of
sight (the zenith, 60° and 85° towards, across and away from the Sun): order 1
(``eclipsed_single_scattering``, 48 samples), order 2 (``eclipsed_second_order`` at its
defaults) and orders >= 3 (``eclipsed_higher_orders`` at its defaults: the table of the dimming
then the final gather; and with one line of sight, which is mostly the table). Medians of
``--repeat`` calls, the cases alternating.

Run: ``python benchmarks/bench_eclipse_higher_orders.py [--append] [--threads 2] [--repeat 3]``.
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._harness import (  # noqa: E402
    alternating_medians,
    argument_parser,
    parse_arguments,
    report_section,
)

BURGOS = (42.34, -3.70, 850.0)
TOTALITY = "2026-08-12T18:29:18"


def main(argv: list[str] | None = None) -> int:
    parser = argument_parser(__doc__.splitlines()[0], repeat=3, threads=2)
    args = parse_arguments(parser, argv)
    import numpy as np
    import torch

    from skytorch.atmosphere import Atmosphere
    from skytorch.atmosphere.multiple_scattering import TableResolution, precompute_scattering
    from skytorch.atmosphere.tables import TransmittanceTable
    from skytorch.scene.eclipse_higher_orders import eclipsed_higher_orders
    from skytorch.scene.geometry import site_geometries
    from skytorch.scene.solar_eclipse_sky import (
        eclipsed_second_order,
        eclipsed_single_scattering,
        sun_direction,
    )

    load_before = os.getloadavg()
    wavelength = torch.tensor([450.0, 550.0, 650.0], dtype=torch.float64)
    atmosphere = Atmosphere.earth(turbidity=2.0)
    tables = precompute_scattering(atmosphere, wavelength, scattering_orders="converged",
                                   resolution=TableResolution(n_r=8, n_mu=32, n_mu_s=16,
                                                              n_phi=6, n_ray=48,
                                                              mu_vertical_weight=0.0,
                                                              r_ground_weight=0.0,
                                                              sphere_phi_refinement=1,
                                                              ray_quadrature="trapezoid"))
    table = TransmittanceTable.build(atmosphere, wavelength, cache=False, n_mu=128, n_r=32)
    geometry = site_geometries(np.datetime64(TOTALITY), [BURGOS[0]], [BURGOS[1]],
                               [BURGOS[2]])[0]
    _, sun_azimuth = sun_direction(geometry)
    views = [(0.0, 0.0)] + [(z, a) for z in (60.0, 85.0) for a in (0.0, 90.0, 180.0)]
    zenith = torch.tensor([math.radians(z) for z, _ in views], dtype=torch.float64)
    azimuth = torch.tensor([float(sun_azimuth) + math.radians(a) for _, a in views],
                           dtype=torch.float64)
    height = BURGOS[2]

    cases = {
        "order 1, 7 lines": lambda: eclipsed_single_scattering(
            atmosphere, wavelength, zenith, azimuth, geometry, height, n_samples=48,
            table=table),
        "order 2, 7 lines": lambda: eclipsed_second_order(
            atmosphere, wavelength, zenith, azimuth, geometry, height, table=table),
        "orders >= 3, 7 lines": lambda: eclipsed_higher_orders(
            atmosphere, wavelength, zenith, azimuth, geometry, height, tables=tables,
            table=table),
        "orders >= 3, 1 line": lambda: eclipsed_higher_orders(
            atmosphere, wavelength, zenith[:1], azimuth[:1], geometry, height, tables=tables,
            table=table),
    }
    medians = alternating_medians(cases, args.repeat, warmup=False)
    second = medians["order 2, 7 lines"]
    rows = [{"case": label, "median [s]": f"{value:.3f}", "vs order 2": f"{value / second:.1f}x"}
            for label, value in medians.items()]
    report_section("Orders >= 3 of the eclipse sky", "bench_eclipse_higher_orders.py",
                   load_before, "Burgos totality, 3 wavelengths, coarse converged tables; "
                   f"medians of {args.repeat} calls, the cases alternating.", rows, args.append)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
