"""The sphere quadrature's azimuths (``sphere_phi_refinement``): accuracy and cost.

References, cases and statistics: :func:`experiments._disort_reference.compare_table_sizes`
(DISORT's sky from the ground, sasktran2's spherical radiance leaving the top).

The source J of each order >= 2 is the previous order scattered by a discrete phase
operator on the sphere quadrature, whose azimuths were the table's own (8 nodes on [0,
pi]: 14 azimuths on the circle, 25.7 deg apart). A Henyey-Greenstein peak of g 0.7 is
about 15 deg wide at half maximum, so the light scattered twice towards the Sun was
aliased on that grid. ``TableResolution.sphere_phi_refinement`` divides each azimuth
interval of the quadrature (the previous order interpolated between the table's azimuths
with its peak shape factored out). For the default table sizes with refinement 1, 2 and 4,
and with the radius nodes crowded towards the ground or doubled: the ray-marched single
scattering plus the tables' orders >= 2 (what scenes render), the largest relative error
over the views and wavelengths and at the vertical, per aerosol optical depth and Sun; and
the precompute time (the optical depths batched in one call).

Writes ``sphere_azimuth_accuracy_cost.nc`` / ``.png``. Run:
``python experiments/sphere_azimuth_accuracy_cost.py [--quick] [--output-dir DIR]``.
``--quick``: the coarse tables of the tests, refinement 1 and 2, 550 nm, optical depth 1.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments._common import parse_arguments  # noqa: E402
from experiments._disort_reference import COARSE, compare_table_sizes  # noqa: E402

#: (name, table sizes on top of the default TableResolution)
#: (the default tables' sizes and quadrature when these were measured)
_TABLES = {"n_r": 16, "ray_quadrature": "trapezoid"}
CASES = (("refinement 1, w 0", {**_TABLES, "sphere_phi_refinement": 1, "r_ground_weight": 0.0}),
         ("refinement 2, w 0", {**_TABLES, "sphere_phi_refinement": 2, "r_ground_weight": 0.0}),
         ("refinement 4, w 0", {**_TABLES, "sphere_phi_refinement": 4, "r_ground_weight": 0.0}),
         ("refinement 1, w 1/2", {**_TABLES, "sphere_phi_refinement": 1, "r_ground_weight": 0.5}),
         ("refinement 2, w 1/2", {**_TABLES, "sphere_phi_refinement": 2, "r_ground_weight": 0.5}),
         ("refinement 2, 32 radii, 192 samples",
          {**_TABLES, "sphere_phi_refinement": 2, "r_ground_weight": 0.0, "n_r": 32,
           "n_ray": 192}))
QUICK_CASES = (("coarse, refinement 1", {**COARSE, "sphere_phi_refinement": 1,
"ray_quadrature": "trapezoid"}),
               ("coarse, refinement 2", {**COARSE, "sphere_phi_refinement": 2}))


def main(argv=None):
    arguments = parse_arguments(__doc__.splitlines()[0], argv)
    compare_table_sizes(
        arguments, CASES, QUICK_CASES, "sphere_azimuth_accuracy_cost",
        "Azimuths of the sphere quadrature: ray-marched order 1 + the tables' orders >= 2 "
        "against flat and spherical references",
        {"sphere_phi_refinement": (lambda sizes: sizes["sphere_phi_refinement"], {}),
         "r_ground_weight": (lambda sizes: sizes["r_ground_weight"], {"units": "1"}),
         "n_r": (lambda sizes: sizes.get("n_r", 16), {}),
         "n_ray": (lambda sizes: sizes.get("n_ray", 96), {})})
    return 0


if __name__ == "__main__":
    sys.exit(main())
