"""The README's tour runs as written."""

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


def test_readme_tour_runs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), re.S)
    assert blocks, "the README has no python example"
    namespace: dict = {}
    for index, code in enumerate(blocks):
        try:
            exec(compile(code, f"README.md[block {index}]", "exec"), namespace)
        except Exception as error:
            pytest.fail(f"README block {index} failed: {error!r}\n{code}")
    assert (tmp_path / "ephemeris.nc").stat().st_size > 1000
    assert tuple(namespace["atm"].transmittance(namespace["wavelength_nm"]).shape) == (5, 4, 3)
    assert namespace["table"].sizes["eclipse"] == 24  # NASA canon, 2020-2029
