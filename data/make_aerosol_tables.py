r"""Regenerate the aerosol Mie tables ``data/aerosol_mie_*.csv`` (development time only).

skytorch never runs this at run time; it reads the tables this script writes. Run with
``python data/make_aerosol_tables.py`` (needs ``miepython``, pinned in constraints.txt);
``--only sulfate|types|mars`` writes one group. The OPAC inputs
(``aerosol_mie_opac_components.csv``) are rebuilt from the OPAC files with
``--opac-src DIR``, the Mars dust table needs ``--mars-src FILE`` (see *Mars dust*).

Model
-----
Stratospheric sulfate droplets (75 % H2SO4 by weight) with a lognormal number size
distribution

.. math:: \frac{dN}{d\ln r} = \frac{N}{\sqrt{2\pi}\ln\sigma_g}
          \exp\left[-\frac{(\ln r - \ln r_g)^2}{2\ln^2\sigma_g}\right],

median radius :math:`r_g = 0.08\,\mu m` and geometric standard deviation
:math:`\sigma_g = 1.8`, the unimodal fit to the background/moderately perturbed
stratospheric layer of the Laramie balloon record (Deshler et al. 2003, ref. 1; Jäger &
Deshler 2002, ref. 2). The refractive index is that of 75 % H2SO4 in the visible,
:math:`m = 1.43 + 10^{-8} i` (Palmer & Williams 1975, ref. 3), held constant over
230–1690 nm: the dispersion of the real part (a few 0.01 over this range) and the rise of
the imaginary part in the near infrared are NOT represented.

Per wavelength the script integrates, over :math:`\ln r` (trapezoid rule on ±6
:math:`\ln\sigma_g`, ``N_NODES`` nodes), the Mie efficiencies of ``miepython``
(:math:`Q_{ext}, Q_{sca}, g`) weighted by the geometric cross-section
:math:`\pi r^2 dN/d\ln r`:

* ``extinction_550``: :math:`\langle C_{ext}\rangle(\lambda)/\langle C_{ext}
  \rangle(550\,nm)`;
* ``single_scattering_albedo``: :math:`\langle C_{sca}\rangle/\langle C_{ext}\rangle`;
* ``asymmetry``: :math:`\langle g\,C_{sca}\rangle/\langle C_{sca}\rangle`.

Tropospheric aerosol types (OPAC)
---------------------------------
The types of Hess et al. 1998 (OPAC, ref. 4, Table 4), external mixtures of lognormal
components with the number densities :math:`N_i` [cm^-3] of :data:`AEROSOL_TYPES`.
Each component (OPAC file name in brackets) has a number size distribution
:math:`dN/d\ln r` of mode radius :math:`r_{mod}`, geometric standard deviation
:math:`\sigma`, truncated to :math:`[r_{min}, r_{max}]`, and a refractive index per
wavelength: insoluble (inso00), water-soluble (waso80), soot (soot00), sea salt
accumulation and coarse (ssam80, sscm80), mineral nucleation, accumulation, coarse and
transported (minm00, miam00, micm00, mitr00), sulfate droplets (suso80). The hygroscopic
components (waso, ssam, sscm, suso) are taken at 80 % relative humidity (wet mode radius
and the volume-mixed index of OPAC's 80 % file; the choice of this script, OPAC also
tabulates 0-99 %). The inputs, extracted from the OPAC files with ``--opac-src`` into
``data/aerosol_mie_opac_components.csv``: r_min, r_max, sigma, r_mod, and at OPAC's 18
wavelengths 250-2000 nm the index n - i k and OPAC's own Mie results (extinction
coefficient for 1 particle cm^-3 [km^-1], single-scattering albedo, asymmetry; used by
the tests as an independent Mie code). Between OPAC's wavelengths n and k are linear in
wavelength; the tables are on a 10 nm grid 250-1000 nm and a 50 nm grid 1000-2000 nm.

Per component the size integral is the trapezoid rule on :func:`component_nodes` nodes
(:data:`N_NODES_COMPONENT`, 600 to 2400) uniform in :math:`\ln r` over
:math:`[r_{min}, r_{max}]` of the normalised lognormal (the truncated tails are not
renormalised, as in OPAC). A type sums the components:
:math:`C_{ext} = \sum N_i C_{ext,i}`, :math:`\omega = \sum N_i C_{sca,i} / C_{ext}`,
:math:`g = \sum N_i g_i C_{sca,i} / \sum N_i C_{sca,i}`; the table has the extinction
relative to 550 nm, :math:`\omega` and :math:`g`.

OPAC source: the OPAC data files as redistributed in github.com/aubema/illumina,
commit cadadca86beaed20d8569147a968be27089ec27d, folder ``Aerosol_optics/OPAC_data/``
(that repository is GPL-3; the numbers are OPAC's, Hess et al. 1998), SHA-256 checked
(:data:`OPAC_SHA256`)::

    git -C <illumina git dir> show cadadca8:Aerosol_optics/OPAC_data/waso80 > src/waso80
    ... (one line per file of OPAC_SHA256)
    python data/make_aerosol_tables.py --opac-src src --only types

Mars dust
---------
Mie single-particle tables (``w0``, ``qext``, ``g0`` on 500 wavelengths 263 nm-98 um x 50
radii 0.05-50 um, miepython) of the Wolff et al. 2009 (ref. 7) Martian dust refractive
index, ``photochem_clima_data/data/aerosol_xsections/marsdust/mie_marsdust.h5`` in
github.com/Nicholaswogan/photochem_clima_data, commit
cba05ffaae3ab7ef11e27bb40570807014d718c0 (GPL-3; SHA-256 :data:`MARS_SHA256`), averaged
over a lognormal with the effective radius 1.5 um and effective variance 0.3 of Wolff et
al. 2009 (:math:`\ln^2\sigma_g = \ln(1 + v_{eff})`, :math:`r_g = r_{eff}
\exp(-2.5\ln^2\sigma_g)`), trapezoid on the source's 50 log-spaced radii (needs h5py)::

    git -C <photochem_clima_data git dir> show cba05ffa:photochem_clima_data/data/\
        aerosol_xsections/marsdust/mie_marsdust.h5 > mie_marsdust.h5
    python data/make_aerosol_tables.py --mars-src mie_marsdust.h5 --only mars

The table ``aerosol_mie_mars_dust.csv`` has the source's wavelengths 263-1712 nm: the
extinction relative to 880 nm, the single-scattering albedo and the asymmetry.

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
4. Hess, M., Koepke, P. & Schult, I. 1998, "Optical Properties of Aerosols and Clouds:
   The Software Package OPAC", Bull. Am. Meteorol. Soc. 79, 831,
   doi:10.1175/1520-0477(1998)079<0831:OPOAAC>2.0.CO;2.
5. Prahl, S. miepython 3.3.0, https://github.com/scottprahl/miepython (MIT).
6. Hansen, J. E. & Travis, L. D. 1974, "Light scattering in planetary atmospheres",
   Space Sci. Rev. 16, 527, doi:10.1007/BF00168069 (effective radius and variance).
7. Wolff, M. J. et al. 2009, "Wavelength dependence of dust aerosol single scattering
   albedo as observed by the Compact Reconnaissance Imaging Spectrometer", J. Geophys.
   Res. 114, E00D04, doi:10.1029/2009JE003350.
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
    r"""Size-averaged cross-sections of the lognormal distribution.

    Parameters
    ----------
    wavelength_nm : array (n,)
        Wavelength [nm].
    n_nodes : int
        Trapezoid nodes over ln r.

    Returns
    -------
    tuple of array (n,)
        :math:`\langle C_{ext}\rangle`, :math:`\langle C_{sca}\rangle` [um^2 per
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


#: OPAC component files (ref. 4) and their SHA-256 in the illumina commit of the docstring
OPAC_SHA256 = {
    "inso00": "752abb463a0d9c6907ca79ec18f1d8a8170d65758f92839381c16bcc854a418d",
    "waso80": "3fbc6c2d87389e11bb20b1272de6a9096bffcc8588799b6146f9d24f464d0564",
    "soot00": "830069fa996cb6e88c7a8c582e68f924068aca061eca5d02d114deab1a8c079e",
    "ssam80": "49ea20ec46d4a72b57aaecef5b90ef1920af9ce6740f2e65361ce92ab0c33fe5",
    "sscm80": "2f40f1187d0f8de86917c253c84d67a1f438ef81f7eebfed54f1a39b7a44a966",
    "minm00": "fbccc059308c95c7cf38276595dd88db074eb098ba6bacff8d339a842c1f6eb4",
    "miam00": "60f33d665a6cf2b2c288198f80f760fb4d11f8acaa0332995023aa0b252592bc",
    "micm00": "f1df7b555acedc46c14dd6915044a7bb8406ee278f3ea864598b55960057ddff",
    "mitr00": "b53f0103cfaa5349d778aec31447e6de65ae9788387b53412cc7210186e0b3f6",
    "suso80": "b34bc717edf87cc287ca1458b28ecab6e96bdfa488d9c6aecd9849cea75ae63a",
}
#: OPAC component of each file (the file name without the humidity)
OPAC_COMPONENTS = tuple(name[:4] for name in OPAC_SHA256)
#: OPAC aerosol types: number density of each component [cm^-3] (Hess et al. 1998,
#: Table 4, as in ``Aerosol_optics/combination_types`` of the illumina commit)
AEROSOL_TYPES = {
    "continental_clean": {"waso": 2600.0, "inso": 0.15},
    "continental_average": {"waso": 7000.0, "inso": 0.4, "soot": 8300.0},
    "continental_polluted": {"waso": 15700.0, "inso": 0.6, "soot": 34300.0},
    "urban": {"waso": 28000.0, "inso": 1.5, "soot": 130000.0},
    "desert": {"waso": 2000.0, "minm": 269.5, "miam": 30.5, "micm": 0.142},
    "maritime_clean": {"waso": 1500.0, "ssam": 20.0, "sscm": 3.2e-3},
    "maritime_polluted": {"waso": 3800.0, "ssam": 20.0, "sscm": 3.2e-3, "soot": 5180.0},
    "maritime_tropical": {"waso": 590.0, "ssam": 10.0, "sscm": 1.3e-3},
    "arctic": {"waso": 1300.0, "inso": 0.01, "ssam": 1.9, "soot": 5300.0},
    "antarctic": {"suso": 42.9, "ssam": 0.047, "mitr": 0.0053},
}
#: wavelengths of the type tables [nm]: 10 nm to 1000 nm, 50 nm beyond (OPAC's indices
#: are given at 1000, 1250, 1500, 1750, 2000 nm there)
TYPE_WAVELENGTH_NM = np.concatenate([np.arange(250.0, 1000.0 + 1e-9, 10.0),
                                     np.arange(1050.0, 2000.0 + 1e-9, 50.0)])
#: nodes of the component size integrals: 600, and more where the area-weighted sizes
#: reach size parameters of several hundred at 250 nm (the interference ripple of
#: Q_ext(x), period ~ pi/(n - 1) in x, must be sampled). Doubling them changes the
#: extinction, albedo and g of the absorbing components by < 1e-4 at 250-1000 nm; for
#: the nearly non-absorbing sea salt and sulfate droplets (k <= 1e-7) the unresolved
#: ripple and resonance structure leaves changes of 1e-4 to 2e-3 that more nodes
#: (tried to 9600) do not remove
#: (experiments/aerosol_mie_accuracy_cost.py, docs/accuracy.md)
N_NODES_OPAC = 600
N_NODES_COMPONENT = {"inso": 1200, "miam": 1200, "micm": 1200, "sscm": 2400}
OPAC_INPUTS = Path(__file__).resolve().parent / "aerosol_mie_opac_components.csv"
OPAC_COLUMNS = ("component", "r_min_um", "r_max_um", "sigma_g", "r_mod_um", "wavelength_nm",
                "n_real", "n_imag", "opac_extinction_per_km", "opac_single_scattering_albedo",
                "opac_asymmetry")
OPAC_RANGE_UM = (0.25, 2.0)

#: Mars dust: effective radius [um] and variance [1] (ref. 7)
MARS_EFFECTIVE_RADIUS_UM = 1.5
MARS_EFFECTIVE_VARIANCE = 0.3
MARS_RANGE_NM = (263.0, 1720.0)  # the source's grid points in it: 263-1712.5 nm
MARS_REFERENCE_NM = 880.0
MARS_SHA256 = "0ffac48881561f07c15903f1a718fb88b9a3d32f1c3729e2732a4972b56a2dae"
MARS_OUTPUT = Path(__file__).resolve().parent / "aerosol_mie_mars_dust.csv"


def type_table_path(name: str) -> Path:
    """Shipped table of the aerosol type ``name``."""
    return Path(__file__).resolve().parent / f"aerosol_mie_{name}.csv"


def _sha256(path: Path) -> str:
    import hashlib

    return hashlib.sha256(path.read_bytes()).hexdigest()


def _parse_opac(path: Path):
    """Size distribution (r_min, r_max, sigma, r_mod wet) and the optical rows of one OPAC file.

    Wavelength [um], ext, sca, abs [km^-1], albedo, g, ext.nor, n, -k.
    """
    import re

    header, rows = {}, []
    for line in path.read_text().splitlines():
        if "phase function" in line:
            break
        match = re.match(r"#\s+(minimum radius|maximum radius|sigma|Rmod \(wet\))"
                         r"[^:]*:\s+(\S+)", line)
        if match:
            header[match.group(1)] = float(match.group(2))
            continue
        fields = line.lstrip("#").split()
        if len(fields) == 9:
            try:
                rows.append([float(v) for v in fields])
            except ValueError:
                continue
    keys = ("minimum radius", "maximum radius", "sigma", "Rmod (wet)")
    return tuple(header[k] for k in keys), np.array(rows)


def extract_opac(source: Path) -> None:
    """Write ``aerosol_mie_opac_components.csv`` from the OPAC files in ``source``."""
    lines = [
        "# OPAC aerosol components (Hess et al. 1998, BAMS 79, 831), extracted by "
        "data/make_aerosol_tables.py",
        "# from the OPAC files of github.com/aubema/illumina@cadadca8 "
        "(Aerosol_optics/OPAC_data/<component><humidity>, humidity 80 % for waso ssam "
        "sscm suso, 0 otherwise)",
        "# lognormal number distribution: r_min r_max r_mod [um] (wet), sigma_g [1]; "
        "refractive index n_real - i n_imag",
        "# OPAC's Mie results for 1 particle cm^-3: extinction [km^-1], single-scattering "
        "albedo, asymmetry",
        ",".join(OPAC_COLUMNS),
    ]
    for name, digest in OPAC_SHA256.items():
        path = source / name
        if _sha256(path) != digest:
            raise ValueError(f"{path}: SHA-256 differs from the expected {digest}")
        (r_min, r_max, sigma, r_mod), rows = _parse_opac(path)
        keep = (rows[:, 0] >= OPAC_RANGE_UM[0] - 1e-9) & (rows[:, 0] <= OPAC_RANGE_UM[1] + 1e-9)
        for row in rows[keep]:
            lines.append(f"{name[:4]},{r_min:.4g},{r_max:.4g},{sigma:.4g},{r_mod:.4g},"
                         f"{row[0] * 1e3:.1f},{row[7]:.4g},{-row[8]:.4g},{row[1]:.4g},"
                         f"{row[4]:.4g},{row[5]:.4g}")
    OPAC_INPUTS.write_text("\n".join(lines) + "\n")
    print(f"wrote {OPAC_INPUTS} ({len(lines) - 5} rows)")


def opac_inputs() -> dict:
    """Return the shipped OPAC inputs per component.

    ``size`` (r_min, r_max, sigma_g, r_mod) [um, um, 1, um] and the arrays ``wavelength_nm``,
    ``n_real``, ``n_imag`` and OPAC's ``extinction_per_km``, ``single_scattering_albedo``,
    ``asymmetry``.
    """
    table = np.genfromtxt(OPAC_INPUTS, delimiter=",", comments="#", skip_header=5,
                          dtype=None, encoding="ascii")
    out = {}
    for name in OPAC_COMPONENTS:
        rows = table[table["f0"] == name]
        out[name] = {
            "size": tuple(float(rows[0][f"f{c}"]) for c in (1, 2, 3, 4)),
            "wavelength_nm": rows["f5"].astype(float),
            "n_real": rows["f6"].astype(float), "n_imag": rows["f7"].astype(float),
            "extinction_per_km": rows["f8"].astype(float),
            "single_scattering_albedo": rows["f9"].astype(float),
            "asymmetry": rows["f10"].astype(float),
        }
    return out


def lognormal_averages(wavelength_nm, refractive_index, *, mode_radius_um: float,
                       geometric_sigma: float, r_min_um: float, r_max_um: float,
                       n_nodes: int):
    r"""Per-particle cross-sections of a lognormal number distribution on [r_min, r_max].

    Parameters
    ----------
    wavelength_nm : array (n,)
        Wavelength [nm].
    refractive_index : array (n,) of complex
        n - i k per wavelength (miepython's sign: absorption negative).
    mode_radius_um, geometric_sigma : float
        Median (mode of dN/dln r) radius [um] and geometric standard deviation [1].
    r_min_um, r_max_um : float
        Bounds of the size integral [um].
    n_nodes : int
        Trapezoid nodes uniform in ln r.

    Returns
    -------
    tuple of array (n,)
        :math:`\langle C_{ext}\rangle`, :math:`\langle C_{sca}\rangle` [um^2] and
        :math:`g` [1].
    """
    import miepython

    log_sigma = np.log(geometric_sigma)
    log_r = np.linspace(np.log(r_min_um), np.log(r_max_um), n_nodes)
    radius = np.exp(log_r)
    weight = (np.exp(-0.5 * ((log_r - np.log(mode_radius_um)) / log_sigma) ** 2)
              / (np.sqrt(2.0 * np.pi) * log_sigma) * (log_r[1] - log_r[0]))
    weight[[0, -1]] *= 0.5
    area = np.pi * radius ** 2
    c_ext, c_sca, g_out = [], [], []
    for wavelength, index in zip(np.atleast_1d(wavelength_nm), np.atleast_1d(refractive_index),
                                 strict=True):
        x = 2.0 * np.pi * radius / (wavelength * 1e-3)
        qext, qsca, _, g = (np.asarray(v, dtype=float) for v in
                            miepython.efficiencies_mx(complex(index), x))
        sca = np.sum(weight * area * qsca)
        c_ext.append(np.sum(weight * area * qext))
        c_sca.append(sca)
        g_out.append(np.sum(weight * area * qsca * g) / sca)
    return np.array(c_ext), np.array(c_sca), np.array(g_out)


def component_nodes(name: str, node_scale: float = 1.0) -> int:
    """Nodes of the size integral of component ``name`` (times ``node_scale``)."""
    return int(round(N_NODES_COMPONENT.get(name, N_NODES_OPAC) * node_scale))


def component_averages(name: str, wavelength_nm, *, node_scale: float = 1.0,
                       span_scale: float = 1.0, inputs: dict | None = None):
    """Return :func:`lognormal_averages` of the OPAC component ``name``.

    With n, k linear in wavelength between OPAC's wavelengths, on :func:`component_nodes` nodes;
    ``span_scale`` < 1 shrinks the ln r interval about ln r_mod (accuracy-cost study).
    """
    data = (inputs or opac_inputs())[name]
    r_min, r_max, sigma, r_mod = data["size"]
    wavelength_nm = np.atleast_1d(np.asarray(wavelength_nm, dtype=float))
    grid = data["wavelength_nm"]
    if wavelength_nm.min() < grid[0] or wavelength_nm.max() > grid[-1]:
        raise ValueError(f"wavelength_nm outside the OPAC inputs {grid[0]}-{grid[-1]} nm")
    index = (np.interp(wavelength_nm, grid, data["n_real"])
             - 1j * np.interp(wavelength_nm, grid, data["n_imag"]))
    low = np.log(r_mod) + span_scale * (np.log(r_min) - np.log(r_mod))
    high = np.log(r_mod) + span_scale * (np.log(r_max) - np.log(r_mod))
    return lognormal_averages(wavelength_nm, index, mode_radius_um=r_mod,
                              geometric_sigma=sigma, r_min_um=float(np.exp(low)),
                              r_max_um=float(np.exp(high)),
                              n_nodes=component_nodes(name, node_scale))


def mix(name: str, components: dict):
    """Return extinction, scattering [um^2 cm^-3] and g [1] of the OPAC type ``name``.

    Mixed from the per-component (C_ext, C_sca, g) of :func:`component_averages`.
    """
    ext = sca = gsca = 0.0
    for component, number in AEROSOL_TYPES[name].items():
        c_ext, c_sca, g = components[component]
        ext = ext + number * c_ext
        sca = sca + number * c_sca
        gsca = gsca + number * c_sca * g
    return ext, sca, gsca / sca


def type_averages(name: str, wavelength_nm, *, node_scale: float = 1.0,
                  span_scale: float = 1.0):
    """:func:`mix` of the components of the OPAC type ``name`` (:data:`AEROSOL_TYPES`)."""
    inputs = opac_inputs()
    components = {c: component_averages(c, wavelength_nm, node_scale=node_scale,
                                        span_scale=span_scale, inputs=inputs)
                  for c in AEROSOL_TYPES[name]}
    return mix(name, components)


def ratio_albedo_g(ext, sca, g):
    """Extinction relative to the last entry (550 nm), albedo and g, without that entry."""
    return ext[:-1] / ext[-1], sca[:-1] / ext[:-1], g[:-1]


def type_table(name: str, wavelength_nm, *, node_scale: float = 1.0,
               span_scale: float = 1.0):
    """Extinction relative to 550 nm, single-scattering albedo and g of a type."""
    wavelength_nm = np.atleast_1d(np.asarray(wavelength_nm, dtype=float))
    return ratio_albedo_g(*type_averages(name, np.append(wavelength_nm, 550.0),
                                         node_scale=node_scale, span_scale=span_scale))


def write_type_tables() -> None:
    inputs = opac_inputs()
    grid = np.append(TYPE_WAVELENGTH_NM, 550.0)
    components = {c: component_averages(c, grid, inputs=inputs) for c in OPAC_COMPONENTS}
    for name, mixture in AEROSOL_TYPES.items():
        ratio, albedo, g = ratio_albedo_g(*mix(name, components))
        composition = ", ".join(f"{c} {n:g}" for c, n in mixture.items())
        lines = [
            f"# OPAC aerosol type {name} (Hess et al. 1998, BAMS 79, 831, Table 4): "
            f"components [cm^-3] {composition}",
            "# Mie theory (miepython 3.3.0) per lognormal component, inputs "
            "data/aerosol_mie_opac_components.csv (80 % relative humidity)",
            "# generated by data/make_aerosol_tables.py; extinction_550: extinction "
            "relative to 550 nm; single_scattering_albedo, asymmetry [1]",
            "wavelength_nm,extinction_550,single_scattering_albedo,asymmetry",
        ]
        for row in zip(TYPE_WAVELENGTH_NM, ratio, albedo, g, strict=True):
            lines.append(f"{row[0]:.1f},{row[1]:.8f},{row[2]:.8f},{row[3]:.8f}")
        path = type_table_path(name)
        path.write_text("\n".join(lines) + "\n")
        print(f"wrote {path} ({len(TYPE_WAVELENGTH_NM)} rows)", flush=True)


def mars_dust_table(source: Path):
    """Wavelength [nm], extinction relative to 880 nm, albedo and g of Martian dust."""
    import h5py

    if _sha256(source) != MARS_SHA256:
        raise ValueError(f"{source}: SHA-256 differs from the expected {MARS_SHA256}")
    with h5py.File(source, "r") as handle:
        wavelength = handle["wavelengths"][:]
        radius = handle["radii"][:]
        w0, qext, g0 = (handle[k][:] for k in ("w0", "qext", "g0"))  # (wavelength, radius)
    log_sigma2 = np.log(1.0 + MARS_EFFECTIVE_VARIANCE)
    r_g = MARS_EFFECTIVE_RADIUS_UM * np.exp(-2.5 * log_sigma2)
    log_r = np.log(radius)
    weight = np.exp(-0.5 * (log_r - np.log(r_g)) ** 2 / log_sigma2) * np.pi * radius ** 2
    step = np.gradient(log_r)  # uniform in ln r: trapezoid with halved end weights
    step[[0, -1]] *= 0.5
    weight = weight * step
    ext = qext @ weight
    sca = (qext * w0) @ weight
    gsca = (qext * w0 * g0) @ weight
    keep = (wavelength >= MARS_RANGE_NM[0] - 0.5) & (wavelength <= MARS_RANGE_NM[1])
    reference = np.interp(MARS_REFERENCE_NM, wavelength, ext)
    return wavelength[keep], ext[keep] / reference, (sca / ext)[keep], (gsca / sca)[keep]


def write_mars_table(source: Path) -> None:
    wavelength, ratio, albedo, g = mars_dust_table(source)
    lines = [
        "# Martian dust, Mie theory: single-particle tables of the Wolff et al. 2009 "
        "(doi:10.1029/2009JE003350) refractive index",
        "# (mie_marsdust.h5 of github.com/Nicholaswogan/photochem_clima_data@cba05ffa, "
        "GPL-3) averaged over a lognormal",
        f"# r_eff = {MARS_EFFECTIVE_RADIUS_UM} um, v_eff = {MARS_EFFECTIVE_VARIANCE}; "
        "generated by data/make_aerosol_tables.py",
        "# extinction_880: extinction relative to 880 nm; single_scattering_albedo, "
        "asymmetry [1]",
        "wavelength_nm,extinction_880,single_scattering_albedo,asymmetry",
    ]
    for row in zip(wavelength, ratio, albedo, g, strict=True):
        lines.append(f"{row[0]:.3f},{row[1]:.8f},{row[2]:.8f},{row[3]:.8f}")
    MARS_OUTPUT.write_text("\n".join(lines) + "\n")
    print(f"wrote {MARS_OUTPUT} ({len(wavelength)} rows)")


def write_sulfate_table() -> None:
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


def main(argv=None) -> int:
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--only", choices=("sulfate", "types", "mars"), default=None)
    parser.add_argument("--opac-src", type=Path, default=None,
                        help="folder with the OPAC files of OPAC_SHA256 (rebuilds the inputs)")
    parser.add_argument("--mars-src", type=Path, default=None, help="mie_marsdust.h5")
    args = parser.parse_args(argv)
    if args.opac_src is not None:
        extract_opac(args.opac_src)
    if args.only in (None, "sulfate"):
        write_sulfate_table()
    if args.only in (None, "types"):
        write_type_tables()
    if args.only in (None, "mars"):
        if args.mars_src is None:
            parser.error("the Mars dust table needs --mars-src (or --only sulfate|types)")
        write_mars_table(args.mars_src)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
