"""The radius nodes crowded towards the ground (``r_ground_weight``): accuracy and cost.

References, cases and statistics: :func:`experiments._disort_reference.compare_table_sizes`
(DISORT's sky from the ground, sasktran2's spherical radiance leaving the top).

An aerosol a kilometre or two deep puts most of the light scattered twice and more below
the third radius node of ref. 2's mapping (16 radii: 0, 0.45, 1.8, 4.0 km), where the
scattered light of the orders >= 2 is interpolated linearly in r. For the default table
sizes with ``TableResolution.r_ground_weight`` 0 (ref. 2), 1/4, 1/2 and 3/4, and for 32
radii on ref. 2's mapping (twice the cost): the ray-marched single scattering plus the
tables' orders >= 2 (what scenes render), the largest relative error over the views and
wavelengths and at the vertical, per aerosol optical depth and Sun; and the precompute time
(the optical depths batched in one call).

Writes ``radius_nodes_accuracy_cost.nc`` / ``.png``. Run:
``python experiments/radius_nodes_accuracy_cost.py [--quick] [--output-dir DIR]``.
``--quick``: the coarse tables of the tests, weights 0 and 1/2, 550 nm, optical depth 1.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import parse_arguments  # noqa: E402
from experiments._disort_reference import COARSE, compare_table_sizes  # noqa: E402

#: (name, table sizes on top of the default TableResolution)
#: (the sphere quadrature on the table's azimuths, 16 radii and the trapezoid along the rays,
#: as when these were measured)
_AZIMUTHS = {"n_r": 16, "sphere_phi_refinement": 1, "ray_quadrature": "trapezoid"}
CASES = (("w 0 (ref. 2)", {**_AZIMUTHS, "r_ground_weight": 0.0}),
         ("w 1/4", {**_AZIMUTHS, "r_ground_weight": 0.25}),
         ("w 1/2", {**_AZIMUTHS, "r_ground_weight": 0.5}),
         ("w 3/4", {**_AZIMUTHS, "r_ground_weight": 0.75}),
         ("32 radii, w 0", {**_AZIMUTHS, "r_ground_weight": 0.0, "n_r": 32}))
QUICK_CASES = (("coarse, w 0", COARSE), ("coarse, w 1/2", {**COARSE, "r_ground_weight": 0.5}))


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    compare_table_sizes(
        arguments, CASES, QUICK_CASES, "radius_nodes_accuracy_cost",
        "Radius nodes crowded towards the ground: ray-marched order 1 + the tables' orders "
        ">= 2 against flat and spherical references",
        {"r_ground_weight": (lambda sizes: sizes.get("r_ground_weight", 0.0), {"units": "1"}),
         "n_r": (lambda sizes: sizes.get("n_r", 16), {})})
    return 0


if __name__ == "__main__":
    sys.exit(main())
