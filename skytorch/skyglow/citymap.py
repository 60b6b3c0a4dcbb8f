"""Synthetic city light maps for examples, tests and benchmarks.

A city is modelled as a population with a radially decreasing density (exponential, as
commonly used for urban population profiles, Clark 1951) whose light output is
proportional to the population, ``flux = lumens_per_capita · population``, plus optional
satellite towns and a smooth synthetic terrain. The map is an ``xarray.Dataset`` with
``flux`` [lm] on ``(y, x)`` in metres east/north and, with terrain, ``altitude`` [m].

References
----------
1. Clark, C. 1951, "Urban population densities", J. R. Stat. Soc. A 114, 490,
   doi:10.2307/2981088.
2. Garstang, R. H. 1986, PASP 98, 364, doi:10.1086/131768 (city light output
   proportional to population).
"""

from __future__ import annotations

import numpy as np

from skytorch._validate import check_int, check_positive, check_range

__all__ = ["point_sources", "synthetic_city"]

#: assumed light output per inhabitant [lm] (order of magnitude of municipal lighting)
DEFAULT_LUMENS_PER_CAPITA = 1000.0


#: largest number of cells along one side of a map
MAX_CELLS_PER_SIDE = 4096


def _grid_size(extent_m, cell_m) -> tuple[float, float]:
    """Validate the map side and cell size [m]: at least one, at most MAX_CELLS_PER_SIDE cells."""
    extent = float(check_positive("extent_m", extent_m, unit=" m"))
    cell = float(check_positive("cell_m", cell_m, unit=" m"))
    n = round(extent / cell)
    if not 1 <= n <= MAX_CELLS_PER_SIDE:
        raise ValueError(f"extent_m / cell_m must give 1 to {MAX_CELLS_PER_SIDE} cells per "
                         f"side; got extent_m={extent:g} m, cell_m={cell:g} m ({n} cells)")
    return extent, cell


def _pair(name: str, value, low=None, high=None, unit=" m") -> tuple[float, float]:
    pair = check_range(name, value, low, high, unit=unit)
    if pair.shape != (2,):
        raise ValueError(f"{name} must be a pair of numbers; got shape {tuple(pair.shape)}")
    return float(pair[0]), float(pair[1])


def _coords(extent_m: float, cell_m: float) -> np.ndarray:
    n = int(round(extent_m / cell_m))
    return (np.arange(n) - (n - 1) / 2.0) * cell_m


def _dataset(x, y, flux, altitude, parameters):
    from skytorch.dataset import VariableSpec, build_dataset, coordinate, variable

    data = {"flux": variable(("y", "x"), flux, VariableSpec(
        "lm", "luminous flux of the cell", "Total luminous flux emitted by the lights of the "
        "cell (all directions)."))}
    if altitude is not None:
        data["altitude"] = variable(("y", "x"), altitude, VariableSpec(
            "m", "ground altitude", "Altitude of the lights above sea level.",
            "surface_altitude"))
    coords = {"x": coordinate("x", x, VariableSpec("m", "easting", "Cell centre east of the "
                                                   "map origin.", "projection_x_coordinate")),
              "y": coordinate("y", y, VariableSpec("m", "northing", "Cell centre north of the "
                                                   "map origin.", "projection_y_coordinate"))}
    return build_dataset(data, coords, title="Synthetic city light map",
                         references=["Clark, C. 1951, J. R. Stat. Soc. A 114, 490, "
                                     "doi:10.2307/2981088"], parameters=parameters)


def synthetic_city(extent_m: float = 40_000.0, cell_m: float = 500.0, *,
                   centre_xy=(0.0, 0.0), population: float = 100_000.0,
                   scale_length_m: float = 2_000.0,
                   lumens_per_capita: float = DEFAULT_LUMENS_PER_CAPITA,
                   n_towns: int = 0, town_population: float = 5_000.0,
                   terrain_amplitude_m: float = 0.0, seed: int = 0):
    """Make a synthetic light map of a city with an exponential population profile.

    Parameters
    ----------
    extent_m : float
        Side of the square map [m], centred on the origin.
    cell_m : float
        Cell size [m].
    centre_xy : (float, float)
        City centre east/north [m], on the map (|x|, |y| ≤ extent_m / 2).
    population : float
        Inhabitants of the main city on the map: the profile is normalised over the map's
        cells, so a city whose profile the map's edge cuts keeps all its inhabitants on
        the map (model a city larger than the map with a larger map).
    scale_length_m : float
        e-folding length of the population density [m].
    lumens_per_capita : float
        Light output per inhabitant [lm] (assumed; default 1000 lm).
    n_towns : int
        Number of small towns placed at random.
    town_population : float
        Inhabitants of each town (scale length 500 m).
    terrain_amplitude_m : float
        Amplitude of a smooth random terrain [m] (0: flat at sea level, no ``altitude``).
    seed : int
        Random seed for towns and terrain.

    Returns
    -------
    xarray.Dataset
        ``flux`` (y, x) [lm], optional ``altitude`` (y, x) [m].

    Examples
    --------
    >>> city = synthetic_city(10_000.0, 1_000.0, population=1e4)
    >>> round(float(city["flux"].sum()) / 1e7, 2)
    1.0
    """
    extent_m, cell_m = _grid_size(extent_m, cell_m)
    half = 0.5 * extent_m
    centre_xy = _pair("centre_xy", centre_xy, -half, half)
    population = float(check_positive("population", population, allow_zero=True))
    scale_length_m = float(check_positive("scale_length_m", scale_length_m, unit=" m"))
    lumens_per_capita = float(check_positive("lumens_per_capita", lumens_per_capita,
                                             allow_zero=True))
    n_towns = check_int("n_towns", n_towns, low=0, high=10_000)
    town_population = float(check_positive("town_population", town_population,
                                           allow_zero=True))
    terrain_amplitude_m = float(check_range("terrain_amplitude_m", terrain_amplitude_m, 0.0,
                                            1e4, unit=" m"))
    seed = check_int("seed", seed, low=0)
    rng = np.random.default_rng(seed)
    x = _coords(extent_m, cell_m)
    y = _coords(extent_m, cell_m)
    xx, yy = np.meshgrid(x, y)

    def blob(cx, cy, people, length):
        density = np.exp(-np.hypot(xx - cx, yy - cy) / length)
        total = density.sum()
        return people * density / total if total > 0 else density

    people = blob(centre_xy[0], centre_xy[1], population, scale_length_m)
    for _ in range(n_towns):
        cx, cy = rng.uniform(x[0], x[-1]), rng.uniform(y[0], y[-1])
        people = people + blob(cx, cy, town_population, 500.0)
    flux = people * lumens_per_capita
    altitude = None
    if terrain_amplitude_m > 0:
        altitude = np.zeros_like(flux)
        for _ in range(4):
            kx, ky = rng.normal(size=2) * 2 * np.pi / extent_m * 2
            phase = rng.uniform(0, 2 * np.pi)
            altitude += np.cos(kx * xx + ky * yy + phase)
        altitude = terrain_amplitude_m * (altitude - altitude.min()) / max(np.ptp(altitude),
                                                                           1e-12)
    parameters = {"extent_m": extent_m, "cell_m": cell_m, "centre_xy": list(centre_xy),
                  "population": population, "scale_length_m": scale_length_m,
                  "lumens_per_capita": lumens_per_capita, "n_towns": n_towns,
                  "town_population": town_population,
                  "terrain_amplitude_m": terrain_amplitude_m, "seed": seed}
    return _dataset(x, y, flux, altitude, parameters)


def point_sources(n: int, extent_m: float = 20_000.0, cell_m: float = 250.0, *,
                  flux_range_lm=(1e5, 1e6), seed: int = 0, exclude_radius_m: float = 0.0):
    """Make a map with ``n`` lit cells at random positions ("lighting cells", Dobashi §5.1).

    Parameters
    ----------
    n : int
        Number of lit cells.
    extent_m, cell_m : float
        Square map side and cell size [m].
    flux_range_lm : (float, float)
        Uniform range of the cells' flux [lm].
    seed : int
    exclude_radius_m : float
        No lit cell within this distance of the origin [m].
    """
    n = check_int("n", n, low=0)
    extent_m, cell_m = _grid_size(extent_m, cell_m)
    low, high = _pair("flux_range_lm", flux_range_lm, 0.0, unit=" lm")
    if low > high:
        raise ValueError(f"flux_range_lm must be (low, high) with low <= high; got "
                         f"{flux_range_lm}")
    seed = check_int("seed", seed, low=0)
    exclude_radius_m = float(check_range("exclude_radius_m", exclude_radius_m, 0.0,
                                         unit=" m"))
    rng = np.random.default_rng(seed)
    x = _coords(extent_m, cell_m)
    y = _coords(extent_m, cell_m)
    xx, yy = np.meshgrid(x, y)
    allowed = np.flatnonzero(np.hypot(xx, yy).ravel() >= exclude_radius_m)
    if n > allowed.size:
        raise ValueError(f"n must be at most {allowed.size} cells for this map; got {n}")
    flux = np.zeros(xx.size)
    chosen = rng.choice(allowed, n, replace=False)
    flux[chosen] = rng.uniform(low, high, n)
    return _dataset(x, y, flux.reshape(xx.shape), None,
                    {"n": n, "extent_m": extent_m, "cell_m": cell_m,
                     "flux_range_lm": [low, high], "seed": seed,
                     "exclude_radius_m": exclude_radius_m})
