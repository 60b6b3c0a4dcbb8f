"""The scene's vocabulary of effects, its fidelity presets and the planner's thresholds.

Everything here is a constant: :data:`EFFECTS` (what the planner decides and the renderer
draws, in composition order), :data:`FIDELITY` (the knobs of the modules per preset,
their measured error and cost in ``docs/scene.md``) and the numbers the planner's bounds
use. The planner (:mod:`skytorch.scene.planner`), the resources
(:mod:`skytorch.scene.resources`) and the renderer (:mod:`skytorch.scene.render`) read
them from here; none of them owns them.

References
----------
1. Willmer, C. N. A. 2018, ApJS 236, 47, doi:10.3847/1538-4365/aabfdf (the Sun's V).
2. Falchi, F. et al. 2016, "The new world atlas of artificial night sky brightness",
   Science Advances 2, e1600377, doi:10.1126/sciadv.1600377.
"""

from __future__ import annotations

import math

__all__ = ["BRIGHTEST_SKYGLOW_MAG_ARCSEC2", "EFFECTS", "FIDELITY", "FIDELITY_PRESETS",
           "HEMISPHERE_ARCSEC2", "HORIZON_REFRACTION_RAD", "MOON_TABLE_DISTANCES",
           "MOON_TABLE_DISTANCE_RANGE_M", "MOON_TABLE_PHASES", "PLANNER_MOON_QUADRATURE",
           "RESOLVED_DISC_PIXELS", "SEMI_DIAMETER_RAD", "SKY_TABLE_SEGMENT_DEG",
           "SKY_TABLE_STEP_DEG", "SUN_V_MAG", "SCATTERING_ORDER_CHOICES"]

#: the planner's vocabulary of effects, in composition order
EFFECTS = ("sky", "sun", "moon", "earthshine", "eclipse", "solar_eclipse", "stars",
           "scintillation", "skyglow", "refraction")

#: V magnitude of the Sun above the atmosphere (Willmer 2018, ApJS 236, 47,
#: doi:10.3847/1538-4365/aabfdf)
SUN_V_MAG = -26.76
#: brightest artificial sky in the world atlas [V mag arcsec^-2] (Falchi et al. 2016)
BRIGHTEST_SKYGLOW_MAG_ARCSEC2 = 14.0
#: apparent semi-diameter of the Sun and Moon used for "above the horizon" [rad]
SEMI_DIAMETER_RAD = math.radians(0.27)
#: refraction at the horizon (standard atmosphere) bounding the upper-limb test [rad]
HORIZON_REFRACTION_RAD = math.radians(0.6)
#: Sun-altitude step of the planner's sky-flux table [degree] (0.5 gives 4 % error in
#: deep twilight, 0.25 below 0.3 %)
SKY_TABLE_STEP_DEG = 0.25
#: ... computed in segments of this many degrees when first needed
SKY_TABLE_SEGMENT_DEG = 5.0
#: hemisphere [arcsec^2]
HEMISPHERE_ARCSEC2 = 2.0 * math.pi * (180.0 * 3600.0 / math.pi) ** 2

#: quadrature nodes of the planner's estimate of the Moon's magnitude (an estimate only)
PLANNER_MOON_QUADRATURE = 8
#: nodes of the planner's table of the Moon's flux over phase angle (2° apart) ...
MOON_TABLE_PHASES = 91
#: ... and over the observer–Moon distance
MOON_TABLE_DISTANCES = 8
#: distances of that table [m]: perigee 356 400 km less the Earth's radius to apogee
#: 406 700 km plus it, rounded outwards
MOON_TABLE_DISTANCE_RANGE_M = (3.45e8, 4.15e8)

#: pixels a disc must cover to be shaded pixel by pixel (fewer: the disc-averaged factor)
RESOLVED_DISC_PIXELS = 16

#: values of ``Scene.scattering_orders`` besides an integer >= 1: the fidelity preset's
#: choice ("auto") or every order to convergence ("converged")
SCATTERING_ORDER_CHOICES = ("auto", "converged")

#: multiple-scattering tables of the presets (:class:`skytorch.atmosphere.multiple_scattering.
#: TableResolution` fields; error and cost in docs/scene.md, experiment scene_ms_accuracy_cost)
#: TableResolution.tiny() but 24 Sun zenith nodes (8 make the twilight 3-4 mag too bright
#: at -12 deg: the linear interpolation across a steep fall in mu_s)
#: (view nodes on ref. 2's mapping, ``mu_vertical_weight`` 0: moving them towards the vertical
#: makes tables of 16 nodes per half worse, docs/multiple_scattering_validation.md); the
#: exponential quadrature along the rays, which their 16 samples need through haze (the sky
#: through an aerosol of τ 1: 113 % → 18 % of DISORT; experiments/ray_quadrature_accuracy_cost.py)
_MS_SMALL = {"n_r": 5, "n_mu": 16, "n_mu_s": 24, "n_phi": 5, "n_ray": 16, "n_sphere_mu": 4,
             "transmittance_r": 16, "transmittance_mu": 32, "mu_vertical_weight": 0.0,
             "r_ground_weight": 0.0, "sphere_phi_refinement": 1,
             "ray_quadrature": "exponential"}
#: the default preset's: 8 radii instead of 5 bring the Rayleigh twilight sky from 27.5 / 35.5 %
#: to 3.8 / 6.0 % of the Monte-Carlo at Sun 94 / 98 deg for 27 % more build time
#: (experiments/preset_radius_nodes_accuracy_cost.py, docs/scene.md); 12 view nodes per half
#: and 8 × 2 sphere directions (since 2026-12-07) take its largest error against the
#: Monte-Carlo from 14.2 to 5.9 % (Sun 30-98 deg) and its orders >= 2 against the converged
#: solver at Sun 98-104 deg from 21-87 % to 8-22 %, for 1.2-1.4x the build
#: (experiments/preset_tables_accuracy_cost.py, docs/scene.md)
_MS_DEFAULT = {**_MS_SMALL, "n_r": 8, "n_mu": 24, "n_sphere_mu": 8, "sphere_phi_refinement": 2}
_MS_COARSE = {"n_r": 8, "n_mu": 32, "n_mu_s": 24, "n_phi": 6, "n_ray": 24, "n_sphere_mu": 6,
              "transmittance_r": 32, "transmittance_mu": 128, "mu_vertical_weight": 0.0,
              "r_ground_weight": 0.0, "sphere_phi_refinement": 1,
              "ray_quadrature": "exponential"}

#: module knobs per fidelity preset (measured error and cost in docs/scene.md);
#: ``scattering_orders`` is what ``Scene.scattering_orders="auto"`` means, ``ms_tables`` the
#: resolution of the tables of orders >= 2 and ``ms_wavelength_nodes`` their wavelengths;
#: ``ms_final_gather`` (or None) corrects the looked-up orders >= 2 by their final gather
#: (:mod:`skytorch.atmosphere.final_gather`, ``quadrature`` = n_view, n_mu, n_phi) on a
#: coarse (zenith, relative azimuth) grid ``lut`` (docs/scene.md); ``eclipse_higher`` (or
#: None) adds the orders >= 3 of the sky at a solar eclipse
#: (:func:`skytorch.scene.eclipse_higher_orders.eclipsed_higher_orders`, ``quadrature`` =
#: n_view, n_mu, n_phi) on a (zenith, absolute azimuth) grid ``lut`` (docs/solar_eclipse_sky.md)
FIDELITY = {
    "fast": {
        "eclipse_sky_lut": (12, 24), "eclipse_samples": 24,
        "eclipse_ms_lut": (4, 8), "eclipse_ms": (12, 4, 16, 8),
        "sky_lut": (12, 13), "sky_samples": 24, "transmittance": (64, 16),
        "moon_lut": (8, 9), "moon_steps": 16, "moon_quadrature": 8,
        "moon_disc_quadrature": 12,
        "scattering_orders": 1, "ms_tables": _MS_SMALL, "ms_wavelength_nodes": 6,
        "ms_final_gather": None, "eclipse_higher": None,
        "skyglow": {"n_azimuth": 32, "n_elevation": 8, "n_distance": 16, "n_components": 4,
                    "max_distance_m": 30_000.0}},
    "default": {
        "eclipse_sky_lut": (24, 48), "eclipse_samples": 48,
        "eclipse_ms_lut": (6, 12), "eclipse_ms": (16, 4, 16, 16),
        "sky_lut": (24, 25), "sky_samples": 48, "transmittance": (128, 32),
        "moon_lut": (12, 13), "moon_steps": 32, "moon_quadrature": 16,
        "moon_disc_quadrature": 24,
        "scattering_orders": "converged", "ms_tables": _MS_DEFAULT, "ms_wavelength_nodes": 6,
        "ms_final_gather": None, "eclipse_higher": None,
        "skyglow": {"n_azimuth": 64, "n_elevation": 16, "n_distance": 32, "n_components": 8,
                    "max_distance_m": 40_000.0}},
    "reference": {
        "eclipse_sky_lut": (48, 96), "eclipse_samples": 96,
        "eclipse_ms_lut": (6, 12), "eclipse_ms": (48, 8, 32, 32),
        "sky_lut": (48, 49), "sky_samples": 128, "transmittance": (256, 64),
        "moon_lut": (24, 25), "moon_steps": 64, "moon_quadrature": 32,
        "moon_disc_quadrature": 48,
        "scattering_orders": "converged", "ms_tables": _MS_COARSE, "ms_wavelength_nodes": 8,
        "ms_final_gather": {"lut": (12, 13), "quadrature": (32, 16, 64)},
        "eclipse_higher": {"lut": (4, 8), "quadrature": (12, 4, 12)},
        "skyglow": {"n_azimuth": 128, "n_elevation": 32, "n_distance": 64,
                    "n_components": 16, "max_distance_m": 40_000.0,
                    "scattering_orders": "converged"}},
}

#: names of the fidelity presets
FIDELITY_PRESETS = tuple(FIDELITY)
