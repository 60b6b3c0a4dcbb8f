r"""Reading TOML text (scene files, sweep configurations).

The standard library's ``tomllib`` on Python >= 3.11; on Python 3.10 the ``tomli``
package (a dependency there), and a clear error when it is missing.

>>> from skytorch._toml import loads
>>> loads('turbidity = 3.0\n[camera]\ntarget = "moon"')
{'turbidity': 3.0, 'camera': {'target': 'moon'}}
"""

from __future__ import annotations

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    try:
        import tomli as tomllib
    except ModuleNotFoundError:
        tomllib = None

__all__ = ["loads"]


def loads(text: str) -> dict:
    """Parse TOML text into a dictionary.

    Parameters
    ----------
    text : str
        The TOML document.

    Returns
    -------
    dict
        Its tables and values.

    Raises
    ------
    ValueError
        When the text is not valid TOML, or on Python 3.10 without ``tomli``.
    """
    if tomllib is None:
        raise ValueError(
            "reading TOML on Python 3.10 needs the 'tomli' package (pip install tomli)")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise ValueError(f"invalid TOML: {error}") from error
