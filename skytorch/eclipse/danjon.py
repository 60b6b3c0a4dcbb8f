r"""Danjon luminosity L of a total lunar eclipse from the Moon's brightness and colour.

:func:`danjon_l` inverts H. C. Vital's correlation between the Danjon number ``L`` and the
visual magnitude ``m`` of the Moon at mid-totality (REA/Lunissolar eclipse reports,
Brazil, 2007–2022),

.. math::

    m = 4.2 - 3 L + (L / 2)^2, \qquad 0 \le L \le 4,

whose slope ``dm/dL = -3 + L/2`` is negative on the whole interval, so the inverse is
unique: ``L = 2 (3 - \sqrt{4.8 + m})`` for ``m`` in ``[m(4), m(0)] = [-3.8, 4.2]``.
Vital quotes his L estimates to ±0.4 (:data:`DANJON_L_UNCERTAINTY`).

**Sign reconstruction.** The stored text of Vital's report on the 2019-01-21 eclipse
prints the relation with a lost minus sign. The sign follows from his worked numbers,
which are published values independent of the formula typed here: L = 2.4 gives
m = −1.56 (2019-01-21 report; his 2010-12-21 report quotes L = 2.4 ± 0.4 → m ≈ −1.6),
and his predictions L = 3.0 → m = −2.6 (2008-02-21 report: "3.0 ± 0.4 and −2.6 ± 0.4")
and L = 2.6 → m = −2.0. With ``+3 L`` the first would be m = +12.8.

:func:`danjon_l_linear` keeps the project's earlier linear brightness proxy (not a
published relation) as a named alternative. :func:`danjon_class_l` reads Danjon's verbal
classes from the modelled umbral centre, the rim-to-centre contrast and the rim colour, as
a cross-check of the brightness-based L.

References
----------
1. Vital, H. C., eclipse reports of the Rede de Astronomia Observacional (REA) /
   Lunissolar: "Report on the Total Lunar Eclipse of Oct. 28, 2004"; "Understanding REA's
   Observations of the Total Lunar Eclipse of February 20-21, 2008"; "Total Lunar Eclipse
   of December 21, 2010, Observation Report and Comments"; the 2019-01-21 report
   (www.geocities.ws/lunissolar2003/).
2. Danjon, A. 1921, "Relation entre l'éclairement de la Lune éclipsée et l'activité
   solaire", L'Astronomie 35, 261; the L classes as published by F. Espenak,
   "Danjon Scale of Lunar Eclipse Brightness" (EclipseWise / NASA).
3. Hernitschek, N., Schmidt, E., Vollmer, M. 2008, Appl. Opt. 47, H62,
   doi:10.1364/AO.47.000H62 (the −3.32 mag anchor of the linear proxy).
"""

from __future__ import annotations

import math

import torch

from skytorch._validate import (
    as_tensor,
    check_broadcastable,
    check_choice,
    check_finite,
    check_flag,
    refuse_gradient,
)

__all__ = [
    "DANJON_ANCHORS",
    "DANJON_L_RANGE",
    "DANJON_L_UNCERTAINTY",
    "DANJON_RELATION",
    "DANJON_RELATION_LINEAR",
    "DANJON_V_RANGE",
    "MOON_B_MINUS_V",
    "OUTSIDE_CHOICES",
    "RIM_CONTRAST_L2",
    "danjon_class_l",
    "danjon_l",
    "danjon_l_linear",
    "vital_magnitude",
]

#: coefficients (a, b, c) of Vital's m = a + b L + c L^2 [mag]
VITAL_COEFFICIENTS = (4.2, -3.0, 0.25)
#: the Danjon scale
DANJON_L_RANGE = (0.0, 4.0)
#: uncertainty Vital quotes for an L estimate (and for L from his correlation) [1]
DANJON_L_UNCERTAINTY = 0.4
#: V magnitudes covered by the correlation, (m(4), m(0)) = (-3.8, 4.2) [mag]
DANJON_V_RANGE = (4.2 - 3.0 * 4.0 + 0.25 * 16.0, 4.2)
#: what :func:`danjon_l` does with a magnitude outside DANJON_V_RANGE
OUTSIDE_CHOICES = ("raise", "nan")
#: how :func:`danjon_l` maps magnitude to L (stored with every light-curve Dataset)
DANJON_RELATION = ("inverse of Vital's correlation m = 4.2 - 3 L + (L/2)^2 (REA eclipse "
                   "reports 2007-2022), L = 2 (3 - sqrt(4.8 + V)), +-0.4; NaN where V is "
                   "outside [-3.8, 4.2] mag")
#: (L, V) anchors of the linear proxy [1], [mag]: L = 4 at V = -3.3 (Hernitschek et al.
#: 2008, 1990-02-09, -3.32 mag) and L = 0 at V = +2 (faint end of Keen 1983's range)
DANJON_ANCHORS = ((0.0, 2.0), (4.0, -3.3))
DANJON_RELATION_LINEAR = ("linear brightness proxy L = 4 (V - 2) / (-3.3 - 2), clipped to "
                          "[0, 4]; not a published L-magnitude relation")
#: B - V of the uneclipsed Moon [mag] (observed; skytorch.moon.reflectance tests)
MOON_B_MINUS_V = 0.92
#: rim-to-centre brightness ratio above which the umbra has Danjon's "very dark central
#: shadow, outer edge relatively bright" (L = 2); the project's reading, 2.5 mag
RIM_CONTRAST_L2 = 10.0


def vital_magnitude(danjon_l) -> torch.Tensor:
    """Visual magnitude of the Moon at mid-totality from the Danjon number (Vital).

    Parameters
    ----------
    danjon_l : Tensor (...)
        Danjon L in [0, 4] [1].

    Returns
    -------
    Tensor (...)
        ``m = 4.2 - 3 L + (L/2)^2`` [mag].

    Raises
    ------
    ValueError
        If ``danjon_l`` is not finite or outside [0, 4].

    Examples
    --------
    >>> round(float(vital_magnitude(2.4)), 2)
    -1.56
    """
    level = check_finite("danjon_l", danjon_l)
    with torch.no_grad():
        bad = (level < DANJON_L_RANGE[0]) | (level > DANJON_L_RANGE[1])
        if bool(bad.any()):
            raise ValueError(f"danjon_l must be in [0, 4]; got {level[bad].flatten()[0].item()!r}")
    a, b, c = VITAL_COEFFICIENTS
    return a + b * level + c * level * level


def danjon_l(v_magnitude, *, outside: str = "raise", return_uncertainty: bool = False):
    """Danjon L from the V magnitude of the Moon at mid-totality (Vital's correlation).

    Inverts ``m = 4.2 - 3 L + (L/2)^2`` on L in [0, 4] (module docstring: provenance and
    the sign reconstruction): ``L = 2 (3 - sqrt(4.8 + m))``, differentiable with
    ``dL/dm = -1 / sqrt(4.8 + m)`` (between -1 at m = -3.8 and -1/3 at m = 4.2).

    Parameters
    ----------
    v_magnitude : Tensor (...)
        V (visual) magnitude of the whole Moon at mid-totality [mag].
    outside : {"raise", "nan"}
        A magnitude outside [-3.8, 4.2] mag (:data:`DANJON_V_RANGE`) raises
        ``ValueError`` (default) or, with ``"nan"``, gives NaN there (used by the
        light-curve Datasets, whose ``danjon_l_relation`` attribute says so).
    return_uncertainty : bool
        Also return the ±0.4 uncertainty of L (:data:`DANJON_L_UNCERTAINTY`).

    Returns
    -------
    Tensor (...) or (Tensor, Tensor)
        L in [0, 4]; with ``return_uncertainty`` also its uncertainty (same shape) [1].

    Raises
    ------
    ValueError
        For a non-finite magnitude (+inf, no light, gives NaN with ``outside="nan"``), or one
        outside [-3.8, 4.2] mag with ``outside="raise"``.

    Examples
    --------
    >>> round(float(danjon_l(-1.56)), 2)
    2.4
    >>> level, sigma = danjon_l(-2.8, return_uncertainty=True)
    >>> round(float(level), 2), float(sigma)
    (3.17, 0.4)
    """
    outside = check_choice("outside", outside, OUTSIDE_CHOICES)
    return_uncertainty = check_flag("return_uncertainty", return_uncertainty)
    v = as_tensor("v_magnitude", v_magnitude)
    # a Moon without light (V = +inf, a black umbra) lies beyond the correlation like
    # any faint one: NaN with outside="nan"
    if outside == "raise" or bool((torch.isnan(v) | (v == -math.inf)).any()):
        v = check_finite("v_magnitude", v)
    low, high = DANJON_V_RANGE
    with torch.no_grad():
        bad = (v < low) | (v > high)
        if outside == "raise" and bool(bad.any()):
            value = v[bad].flatten()[0].item()
            raise ValueError(f"v_magnitude must be in [{low:g}, {high:g}] mag (Vital's "
                             f"correlation covers Danjon L 0-4); got {value!r}")
    # inside the range 4.8 + v >= 1; the where keeps the gradient finite at NaN members
    root = torch.sqrt(torch.where(bad, torch.ones_like(v), 4.8 + v))
    level = 2.0 * (3.0 - root)
    if bool(bad.any()):
        level = torch.where(bad, torch.full_like(level, float("nan")), level)
    if return_uncertainty:
        return level, torch.full_like(level, DANJON_L_UNCERTAINTY)
    return level


def danjon_l_linear(v_magnitude) -> torch.Tensor:
    """Return the earlier linear brightness proxy for Danjon L (a named alternative).

    **Not a published L–magnitude relation** (:data:`DANJON_RELATION_LINEAR`): L is linear
    in V between the anchors :data:`DANJON_ANCHORS`, ``L = 4 (V - 2) / (-3.3 - 2)``, and
    clipped to [0, 4] (documented here; the clip is the point of a scale proxy). L = 4 at
    V = -3.3, the brightest totality measured photometrically by Hernitschek et al. 2008
    (-3.32 mag, 1990-02-09); L = 0 at V = +2. It ignores colour and the rim brightness.
    :func:`danjon_l` (Vital's correlation) replaces it.

    Parameters
    ----------
    v_magnitude : Tensor (...)
        V magnitude at greatest eclipse [mag].

    Returns
    -------
    Tensor (...)
        L in [0, 4].

    Examples
    --------
    >>> round(float(danjon_l_linear(-0.65)), 2)
    2.0
    """
    v = check_finite("v_magnitude", v_magnitude)
    (l0, v0), (l1, v1) = DANJON_ANCHORS
    return torch.clamp(l0 + (v - v0) * (l1 - l0) / (v1 - v0), 0.0, 4.0)


def danjon_class_l(centre_v_magnitude, rim_to_centre, rim_b_minus_v) -> torch.Tensor:
    """Danjon's verbal class (0–4) read from the modelled umbra, a cross-check of L.

    Danjon's classes (1921, as published by Espenak): L = 0 very dark, Moon almost
    invisible at mid-totality; 1 dark, grey or brownish, details hard to see; 2 deep red
    or rust, very dark central shadow while the outer edge of the umbra is relatively
    bright; 3 brick-red, the umbra usually with a bright or yellow rim; 4 very bright
    copper-red or orange, with a bluish, very bright rim. The mapping (the project's
    reading of those words, stated so that it can be argued with):

    1. **brightness**: the centre of the umbra gives a class by Vital's correlation
       (:func:`danjon_l`) applied to ``centre_v_magnitude``, the magnitude the whole Moon
       would have if it were as bright as the umbral centre, rounded to the nearest
       integer; fainter than V(L=0) = 4.2 is class 0 and brighter than V(L=4) = -3.8 is
       class 4 (the ends of the scale, not a clamp of a continuous value);
    2. **bright rim over a very dark centre**: a class 0 or 1 centre whose rim is at least
       :data:`RIM_CONTRAST_L2` (10×, 2.5 mag) brighter is class 2 ("very dark central
       shadow, outer edge relatively bright");
    3. **bluish rim**: class 4 needs a rim bluer than the uneclipsed Moon
       (``rim_b_minus_v < 0.92``, :data:`MOON_B_MINUS_V`); otherwise it is class 3
       ("bright or yellow rim").

    Parameters
    ----------
    centre_v_magnitude : Tensor (...)
        V magnitude of a Moon uniformly as bright as the umbral centre [mag].
    rim_to_centre : Tensor (...)
        Brightness of the umbral rim (just inside the umbra's edge) over that of the
        centre, > 0 [1].
    rim_b_minus_v : Tensor (...)
        B − V colour of the light at the rim [mag].

    Returns
    -------
    Tensor (...)
        Class 0–4 (integer values, dtype of the inputs); not differentiable (a class).

    Examples
    --------
    >>> float(danjon_class_l(-3.9, 3.0, 0.5)), float(danjon_class_l(-3.9, 3.0, 1.5))
    (4.0, 3.0)
    >>> float(danjon_class_l(3.0, 30.0, 1.8))
    2.0
    """
    # a class has no gradient: one asked for is refused, not dropped
    refuse_gradient("danjon_class_l", why="a class, a whole number",
                    centre_v_magnitude=centre_v_magnitude,
                    rim_to_centre=rim_to_centre, rim_b_minus_v=rim_b_minus_v)
    centre = check_finite("centre_v_magnitude", centre_v_magnitude)
    ratio = check_finite("rim_to_centre", rim_to_centre, dtype=centre.dtype)
    colour = check_finite("rim_b_minus_v", rim_b_minus_v, dtype=centre.dtype)
    check_broadcastable(centre_v_magnitude=centre, rim_to_centre=ratio, rim_b_minus_v=colour)
    with torch.no_grad():
        if bool((ratio <= 0).any()):
            value = ratio[ratio <= 0].flatten()[0].item()
            raise ValueError(f"rim_to_centre must be > 0; got {value!r}")
        centre, ratio, colour = torch.broadcast_tensors(centre, ratio, colour)
        low, high = DANJON_V_RANGE
        inside = torch.clamp(centre, low, high)  # only to evaluate; ends set below
        level = torch.round(danjon_l(inside))
        level = torch.where(centre > high, torch.zeros_like(level), level)
        level = torch.where(centre < low, torch.full_like(level, 4.0), level)
        level = torch.where((level <= 1.0) & (ratio >= RIM_CONTRAST_L2),
                            torch.full_like(level, 2.0), level)
        level = torch.where((level == 4.0) & (colour >= MOON_B_MINUS_V),
                            torch.full_like(level, 3.0), level)
    return level
