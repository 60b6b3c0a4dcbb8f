"""Regenerate the spectral tables shipped in ``data/`` (development time only).

skytorch never runs this at run time and never imports the packages used here. The
tables are extracted from published datasets redistributed by three Python packages:

* colour-science (BSD-3): CIE 1931 2-degree colour-matching functions and the CIE 1924
  photopic luminous efficiency function V(lambda), as tabulated by the CIE
  (CIE 015:2004 "Colorimetry", 3rd ed.; CIE 018:2019 / ISO 11664-1:2019), 1 nm steps.
* speclite (BSD-3): Johnson-Cousins B, V, R_C and I_C passbands of Bessell, M. S. 1990,
  "UBVRI passbands", PASP 102, 1181, doi:10.1086/132749, Table 2 (normalised response).
* pvlib (BSD-3): the extraterrestrial ("Etr") column of the ASTM G173-03 reference
  spectra (SMARTS v2.9.2, Gueymard 2004 composite extraterrestrial spectrum close to
  ASTM E-490), 280-4000 nm, W m^-2 nm^-1 at 1 AU. Bruneton's precomputed atmospheric
  scattering demo (2017) bins the same column into its 360-830 nm solar spectrum.

Usage (from the repository root)::

    pip install colour-science
    pip download --no-deps speclite pvlib -d /tmp/wheels
    (cd /tmp/wheels && for w in *.whl; do unzip -o -q "$w"; done)
    python data/make_tables.py --wheel-dir /tmp/wheels
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
CIE_RANGE_NM = (360, 830)


def _write(name: str, header: list[str], columns: list[str], rows: np.ndarray, fmt: str):
    path = HERE / name
    with path.open("w") as handle:
        for line in header:
            handle.write(f"# {line}\n")
        handle.write(",".join(columns) + "\n")
        for row in rows:
            handle.write(",".join(fmt.format(v) for v in row) + "\n")
    print(f"wrote {path} ({len(rows)} rows)")


def cie_tables() -> None:
    import colour

    wavelength = np.arange(CIE_RANGE_NM[0], CIE_RANGE_NM[1] + 1, dtype=float)
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    xyz = np.asarray(cmfs[wavelength])
    _write(
        "cie1931_2deg_cmf.csv",
        ["CIE 1931 2-degree standard observer colour-matching functions, 360-830 nm, 1 nm.",
         "Source: CIE 015:2004 Colorimetry 3rd ed. / CIE 018:2019, as redistributed by",
         f"colour-science {colour.__version__}",
         "(MSDS_CMFS['CIE 1931 2 Degree Standard Observer'])."],
        ["wavelength_nm", "x_bar", "y_bar", "z_bar"],
        np.column_stack([wavelength, xyz]), "{:.7g}",
    )
    lef = colour.SDS_LEFS["CIE 1924 Photopic Standard Observer"]
    _write(
        "cie1924_photopic_v.csv",
        ["CIE 1924 photopic luminous efficiency function V(lambda), 360-830 nm, 1 nm.",
         "Source: CIE 018:2019 / ISO 23539:2005(E)/CIE S 010/E:2004, as redistributed by",
         f"colour-science {colour.__version__}",
         "(SDS_LEFS['CIE 1924 Photopic Standard Observer'])."],
        ["wavelength_nm", "v"],
        np.column_stack([wavelength, np.asarray(lef[wavelength])]), "{:.7g}",
    )


def _read_ecsv(path: Path) -> np.ndarray:
    lines = [ln for ln in path.read_text().splitlines() if ln and not ln.startswith("#")]
    return np.array([[float(v) for v in ln.split()] for ln in lines[1:]])


def bessell_tables(wheel_dir: Path) -> None:
    for band in ("B", "V", "R", "I"):
        table = _read_ecsv(wheel_dir / "speclite" / "data" / "filters" / f"bessell-{band}.ecsv")
        table[:, 0] /= 10.0  # Angstrom -> nm
        _write(
            f"bessell1990_{band.lower()}.csv",
            [f"Johnson-Cousins {band}{'_C' if band in 'RI' else ''} passband, normalised "
             "response (maximum 1).",
             "Source: Bessell, M. S. 1990, PASP 102, 1181, doi:10.1086/132749, Table 2,",
             f"as redistributed by speclite (bessell-{band}.ecsv). Response for energy",
             "integration (Bessell & Murphy 2012, PASP 124, 140, doi:10.1086/664083)."],
            ["wavelength_nm", "response"], table, "{:.6g}",
        )


def solar_table(wheel_dir: Path) -> None:
    raw = np.genfromtxt(wheel_dir / "pvlib" / "data" / "ASTMG173.csv", delimiter=",",
                        skip_header=2)
    _write(
        "astm_g173_extraterrestrial.csv",
        ["Solar spectral irradiance at 1 AU above the atmosphere [W m^-2 nm^-1], 280-4000 nm.",
         "Source: ASTM G173-03 reference spectra (SMARTS v2.9.2), extraterrestrial column;",
         "Gueymard, C. A. 2004, Solar Energy 76, 423, doi:10.1016/j.solener.2003.08.039;",
         "as redistributed by pvlib (pvlib/data/ASTMG173.csv)."],
        ["wavelength_nm", "irradiance_w_m2_nm"], raw[:, :2], "{:.6g}",
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--wheel-dir", type=Path, required=True,
                        help="folder with the unpacked speclite and pvlib wheels")
    args = parser.parse_args()
    cie_tables()
    bessell_tables(args.wheel_dir)
    solar_table(args.wheel_dir)


if __name__ == "__main__":
    main()
