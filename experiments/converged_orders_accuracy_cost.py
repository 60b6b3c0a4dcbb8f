"""When to stop adding orders of scattering: accuracy and cost of the ``"converged"`` rule.

``precompute_scattering(..., scattering_orders="converged")`` on the default scene preset's
tables (8 radii × 16 view × 24 Sun-zenith × 5 azimuth nodes, 16 samples per ray) at 6
wavelengths 400-700 nm, for turbidity 1.5 / 3 / 6 over a black ground and a ground of albedo
0.3. The reference is the same tables' series carried to 40 orders (its last order below
1e-7 of the sum): the error is the largest |radiance / reference - 1| over 16 view zeniths
0-86 deg × 5 azimuths × 6 wavelengths, per Sun zenith 20-108 deg, seen from the ground.
Compared: every fixed number of orders N; the former rule (stop when the last order is below
1e-4 of the sum over the whole table); the present rule (stop when the sum with its
remainder extrapolated as a geometric series, ratio per table node, changes by less than
1e-4 of each Sun-zenith node's sum). Cost: CPU time of the build (all threads), median of 3.

Writes ``converged_orders_accuracy_cost.nc`` / ``.png``. Run:
``python experiments/converged_orders_accuracy_cost.py [--quick] [--output-dir DIR]``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import torch
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import median_cpu_seconds, parse_arguments, save_outputs  # noqa: E402
from skytorch.atmosphere import Atmosphere  # noqa: E402
from skytorch.atmosphere.multiple_scattering import (  # noqa: E402
    CONVERGENCE_RTOL,
    TableResolution,
    precompute_scattering,
)
from skytorch.scene.presets import FIDELITY  # noqa: E402

F64 = torch.float64
CASES = ((1.5, 0.0), (1.5, 0.3), (3.0, 0.0), (3.0, 0.3), (6.0, 0.0), (6.0, 0.3))
SUN_ZENITH_DEG = (20.0, 45.0, 60.0, 75.0, 85.0, 90.0, 92.0, 94.0, 96.0, 98.0, 100.0, 102.0,
                  104.0, 106.0, 108.0)
SERIES_ORDERS = 40
MAX_FIXED = 20


def _geometry():
    view = torch.linspace(0.0, 1.5, 16, dtype=F64)[:, None, None]
    azimuth = torch.linspace(0.0, 3.14, 5, dtype=F64)[None, :, None]
    sun = torch.deg2rad(torch.tensor(SUN_ZENITH_DEG, dtype=F64))[None, None, :]
    return 0.0, view, azimuth, sun


def _error(value, reference):
    """Largest relative error per Sun zenith (over views, azimuths, wavelengths)."""
    return ((value - reference).abs() / reference).amax(dim=(0, 1, 3)).numpy()


def former_rule_orders(contributions: np.ndarray) -> int:
    """Orders at which the former rule stopped: the last order <= 1e-4 of the sum."""
    for n in range(2, len(contributions) + 1):
        if contributions[n - 1] <= CONVERGENCE_RTOL * contributions[:n].sum():
            return n
    raise ValueError(f"the former rule does not stop within {len(contributions)} orders")


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    import matplotlib.pyplot as plt

    quick = arguments.quick
    cases = CASES[:1] if quick else CASES
    resolution = TableResolution(**FIDELITY["fast" if quick else "default"]["ms_tables"])
    wavelength = torch.linspace(400.0, 700.0, 2 if quick else 6, dtype=F64)
    repeat = 1 if quick else 3
    geometry = _geometry()
    n_sun = len(SUN_ZENITH_DEG)
    fixed = np.full((len(cases), MAX_FIXED, n_sun), np.nan)
    rules = np.zeros((len(cases), 2, n_sun))
    orders = np.zeros((len(cases), 2), dtype=np.int64)
    seconds = np.zeros((len(cases), 2))
    last_order = np.zeros(len(cases))
    for i, (turbidity, albedo) in enumerate(cases):
        atmosphere = Atmosphere.earth(turbidity=turbidity, ozone_du=300.0)

        def build(scattering_orders, atmosphere=atmosphere, albedo=albedo):
            return precompute_scattering(atmosphere, wavelength, ground_albedo=albedo,
                                         scattering_orders=scattering_orders,
                                         resolution=resolution)
        series = build(SERIES_ORDERS)
        contributions = series.order_contributions.numpy()
        last_order[i] = contributions[-1] / contributions.sum()
        reference = series.radiance(*geometry)
        for n in range(1, MAX_FIXED + 1):
            fixed[i, n - 1] = _error(series.radiance(*geometry, scattering_orders=n), reference)
        former = former_rule_orders(contributions)
        orders[i, 0] = former
        rules[i, 0] = fixed[i, former - 1]
        seconds[i, 0] = median_cpu_seconds(lambda former=former: build(former), repeat)
        converged = build("converged")
        orders[i, 1] = converged.orders_computed
        rules[i, 1] = _error(converged.radiance(*geometry), reference)
        seconds[i, 1] = median_cpu_seconds(lambda: build("converged"), repeat)
    labels = [f"turbidity {t}, albedo {a}" for t, a in cases]
    rule_names = ["last order <= 1e-4 of the table's sum (until 2026-12-06)",
                  "sum + geometric remainder changes <= 1e-4 per Sun node (since 2026-12-06)"]
    dataset = xr.Dataset(
        {"fixed_orders_error": (("case", "orders", "sun_zenith"), fixed,
                                {"units": "1", "long_name": "largest |orders 1..N / series - 1| "
                                 "over views, azimuths and wavelengths"}),
         "rule_error": (("case", "rule", "sun_zenith"), rules,
                        {"units": "1", "long_name": "largest |converged / series - 1| over "
                         "views, azimuths and wavelengths"}),
         "rule_orders": (("case", "rule"), orders,
                         {"units": "1", "long_name": "orders computed"}),
         "build_seconds": (("case", "rule"), seconds,
                           {"units": "s", "long_name": "CPU time of the build, median"}),
         "series_last_order": (("case",), last_order,
                               {"units": "1", "long_name": "the reference's last order "
                                "relative to its sum"})},
        coords={"case": ("case", np.array(labels)),
                "orders": ("orders", np.arange(1, MAX_FIXED + 1)),
                "rule": ("rule", np.array(rule_names)),
                "sun_zenith": ("sun_zenith", np.array(SUN_ZENITH_DEG), {"units": "degree"})},
        attrs={"title": "Stopping rule of the converged orders of scattering: error against "
                        f"{SERIES_ORDERS} orders and cost",
               "table_sizes": str(resolution),
               "wavelengths_nm": str(wavelength.tolist()),
               "torch_threads": torch.get_num_threads()})
    figure, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for i, label in enumerate(labels):
        worst = np.nanmax(fixed[i], axis=-1)
        axes[0].semilogy(np.arange(1, MAX_FIXED + 1), worst, "-", color=f"C{i}", label=label)
        for r, marker in enumerate(("s", "*")):
            axes[0].semilogy(orders[i, r], rules[i, r].max(), marker, color=f"C{i}", ms=8)
        axes[1].semilogy(SUN_ZENITH_DEG, rules[i, 0], "s--", color=f"C{i}", ms=3)
        axes[1].semilogy(SUN_ZENITH_DEG, rules[i, 1], "*-", color=f"C{i}", ms=5, label=label)
    axes[0].set_xlabel("orders N")
    axes[0].set_ylabel("largest error against the series")
    axes[0].set_title("lines: orders 1..N; squares: former rule; stars: present rule",
                      fontsize=8)
    axes[0].legend(fontsize=6)
    axes[1].set_xlabel("Sun zenith [deg]")
    axes[1].set_ylabel("largest error against the series")
    axes[1].set_title("dashed: former rule; solid: present rule", fontsize=8)
    figure.tight_layout()
    save_outputs(dataset, figure, arguments.output_dir, "converged_orders_accuracy_cost")
    for i, label in enumerate(labels):
        print(f"{label}: former {orders[i, 0]} orders, {rules[i, 0].max():.1e}, "
              f"{seconds[i, 0]:.2f} s; present {orders[i, 1]} orders, "
              f"{rules[i, 1].max():.1e}, {seconds[i, 1]:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
