"""Every python block of docs/user_guide.md runs, in order, in one namespace."""

import re
from pathlib import Path

import pytest

GUIDE = Path(__file__).resolve().parents[1] / "docs" / "user_guide.md"


def blocks():
    return re.findall(r"```python\n(.*?)```", GUIDE.read_text(encoding="utf-8"), re.S)


def test_the_guide_has_examples():
    assert len(blocks()) >= 8


def test_user_guide_examples_run(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    for index, code in enumerate(blocks()):
        try:
            exec(compile(code, f"{GUIDE.name}[block {index}]", "exec"), namespace)
        except Exception as error:  # name the failing block
            pytest.fail(f"user guide block {index} failed: {error!r}\n{code}")
    assert (tmp_path / "paris.png").stat().st_size > 100
