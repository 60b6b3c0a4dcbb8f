"""Regenerate ``data/aerosol_mie_sulfate.csv`` (development time only).

skytorch never runs this at run time; it reads the table this script writes. Run with
``python data/make_aerosol_tables.py`` (needs ``miepython``, pinned in constraints.txt).

Model
-----
Stratospheric sulfate droplets (75 % H2SO4 by weight) with a lognormal number size
distribution

.. math:: \\frac{dN}{d\\ln r} = \\frac{N}{\\sqrt{2\\pi}\\ln\\sigma_g}
          \\exp\\left[-\\frac{(\\ln r - \\ln r_g)^2}{2\\ln^2\\sigma_g}\\right],

median radius :math:`r_g = 0.08\\,\\mu m` and geometric standard deviation
:math:`\\sigma_g = 1.8`, the unimodal fit to the background/moderately perturbed
stratospheric layer of the Laramie balloon record (Deshler et al. 2003, ref. 1; Jäger &
Deshler 2002, ref. 2). The refractive index is that of 75 % H2SO4 in the visible,
:math:`m = 1.43 + 10^{-8} i` (Palmer & Williams 1975, ref. 3), held constant over
230–1690 nm: the dispersion of the real part (a few 0.01 over this range) and the rise of
the imaginary part in the near infrared are NOT represented.

Per wavelength the script integrates, over :math:`\\ln r` (trapezoid rule on ±6
:math:`\\ln\\sigma_g`, ``N_NODES`` nodes), the Mie efficiencies of ``miepython``
(:math:`Q_{ext}, Q_{sca}, g`) weighted by the geometric cross-section
:math:`\\pi r^2 dN/d\\ln r`:

* ``extinction_550``: :math:`\\langle C_{ext}\\rangle(\\lambda)/\\langle C_{ext}
  \\rangle(550\\,nm)`;
* ``single_scattering_albedo``: :math:`\\langle C_{sca}\\rangle/\\langle C_{ext}\\rangle`;
* ``asymmetry``: :math:`\\langle g\\,C_{sca}\\rangle/\\langle C_{sca}\\rangle`.

References
----------
1. Deshler, T. et al. 2003, "Thirty years of in situ stratospheric aerosol size
   distribution measurements from Laramie, Wyoming (41°N), using balloon-borne
   instruments", J. Geophys. Res. 108(D5), 4167, doi:10.1029/2002JD002514.
2. Jäger, H. & Deshler, T. 2002, "Lidar backscatter to extinction, mass and area
   conversions for stratospheric aerosols based on midlatitude balloonborne size
   distribution measurements", Geophys. Res. Lett. 29(19), 1929,
   doi:10.1029/2002GL015609.
3. Palmer, K. F. & Williams, D. 1975, "Optical constants of sulfuric acid; application
   to the clouds of Venus?", Appl. Opt. 14, 208, doi:10.1364/AO.14.000208.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

#: lognormal median radius [um] and geometric standard deviation [1] (refs. 1, 2)
MEDIAN_RADIUS_UM = 0.08
GEOMETRIC_SIGMA = 1.8
#: refractive index of 75 % H2SO4 in the visible (ref. 3); miepython's sign convention
#: has absorption as a negative imaginary part
REFRACTIVE_INDEX = complex(1.43, -1e-8)
#: wavelengths of the table [nm]
WAVELENGTH_NM = np.arange(230.0, 1690.0 + 1e-9, 10.0)
#: nodes of the size integral (doubling them changes the extinction by < 1e-3)
N_NODES = 400
#: half width of the size integral [ln sigma_g]
HALF_WIDTH_SIGMA = 6.0

OUTPUT = Path(__file__).resolve().parent / "aerosol_mie_sulfate.csv"


def size_averages(wavelength_nm, *, n_nodes: int = N_NODES,
                  median_radius_um: float = MEDIAN_RADIUS_UM,
                  geometric_sigma: float = GEOMETRIC_SIGMA,
                  refractive_index: complex = REFRACTIVE_INDEX):
    """Size-averaged cross-sections of the lognormal distribution.

    Parameters
    ----------
    wavelength_nm : array (n,)
        Wavelength [nm].
    n_nodes : int
        Trapezoid nodes over ln r.

    Returns
    -------
    tuple of array (n,)
        :math:`\\langle C_{ext}\\rangle`, :math:`\\langle C_{sca}\\rangle` [um^2 per
        particle] and the asymmetry parameter :math:`g` [1].
    """
    import miepython

    log_sigma = np.log(geometric_sigma)
    t = np.linspace(-HALF_WIDTH_SIGMA, HALF_WIDTH_SIGMA, n_nodes)
    radius = median_radius_um * np.exp(t * log_sigma)
    weight = np.exp(-0.5 * t ** 2) / np.sqrt(2.0 * np.pi) * (t[1] - t[0])  # dN/N over dt
    weight[[0, -1]] *= 0.5
    area = np.pi * radius ** 2
    c_ext, c_sca, g_out = [], [], []
    for wavelength in np.atleast_1d(np.asarray(wavelength_nm, dtype=float)):
        x = 2.0 * np.pi * radius / (wavelength * 1e-3)
        qext, qsca, _, g = (np.asarray(v, dtype=float) for v in
                            miepython.efficiencies_mx(refractive_index, x))
        ext = np.sum(weight * area * qext)
        sca = np.sum(weight * area * qsca)
        c_ext.append(ext)
        c_sca.append(sca)
        g_out.append(np.sum(weight * area * qsca * g) / sca)
    return np.array(c_ext), np.array(c_sca), np.array(g_out)


def main(argv=None) -> int:
    c_ext, c_sca, g = size_averages(WAVELENGTH_NM)
    reference, _, _ = size_averages(np.array([550.0]))
    lines = [
        "# Stratospheric sulfate aerosol (75 % H2SO4), Mie theory (miepython 3.3.0) for a",
        f"# lognormal size distribution r_g = {MEDIAN_RADIUS_UM} um, sigma_g = "
        f"{GEOMETRIC_SIGMA} (Deshler et al. 2003, doi:10.1029/2002JD002514),",
        "# m = 1.43 + 1e-8 i at every wavelength (Palmer & Williams 1975, "
        "doi:10.1364/AO.14.000208); generated by data/make_aerosol_tables.py",
        "# extinction_550: extinction cross-section relative to 550 nm; "
        "single_scattering_albedo, asymmetry [1]",
        "wavelength_nm,extinction_550,single_scattering_albedo,asymmetry",
    ]
    for row in zip(WAVELENGTH_NM, c_ext / reference[0], c_sca / c_ext, g, strict=True):
        lines.append(f"{row[0]:.1f},{row[1]:.8f},{row[2]:.10f},{row[3]:.8f}")
    OUTPUT.write_text("\n".join(lines) + "\n")
    print(f"wrote {OUTPUT} ({len(WAVELENGTH_NM)} rows)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
