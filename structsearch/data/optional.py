"""Optional dependencies, imported where a command needs them, with one error that says how to install them."""
from __future__ import annotations

from .errors import StructSearchError


def need_jsbsim(what: str):
    """The jsbsim module, or one error saying that ``what`` needs it and how to install it."""
    try:
        import jsbsim
    except ImportError:
        raise StructSearchError(f"{what}: install it with `pip install structsearch[jsbsim]` "
                                "(or `pip install jsbsim`)") from None
    return jsbsim
