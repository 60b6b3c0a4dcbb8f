"""Benchmark: a 512 x 512 all-sky render at totality (Burgos, 2026-08-12), median of runs.

Side by side: the sky single-scattered (``scattering_orders=1``) and with its second
order (the preset's orders: 1 and 2 during a solar eclipse), both with the Sun's visible
fraction at every scattering (skytorch.scene.solar_eclipse_sky). Each run renders with
warm resources (tables and geometry built once); the eclipse sky tables are per instant
and are rebuilt in every run.
Usage: OMP_NUM_THREADS=1 python benchmarks/bench_scene_solar_eclipse.py [--size N] [--repeat N]
"""

import argparse
import statistics
import time

import skytorch as st


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--fidelity", default="default")
    args = parser.parse_args()
    for orders in (1, "auto"):
        scene = st.Scene(time="2026-08-12T18:29:18", lat_deg=42.34, lon_deg=-3.70,
                         elevation_m=850.0, view="fisheye", size=args.size,
                         fidelity=args.fidelity, scattering_orders=orders)
        resources = scene.resources()
        scene.render(resources=resources)  # tables and geometry built once
        seconds = []
        for _ in range(args.repeat):
            start = time.perf_counter()
            frame = scene.render(resources=resources)
            seconds.append(time.perf_counter() - start)
        print(f"{args.size}^2 all-sky at totality ({args.fidelity}, scattering_orders="
              f"{orders!r}, sky orders {frame.attrs['sky_scattering_orders']}): median "
              f"{statistics.median(seconds):.3f} s over {args.repeat}; computed "
              f"{frame.attrs['effects_computed']}")


if __name__ == "__main__":
    main()
