"""structsearch: model-structure search for aircraft stall aerodynamics."""
from .errors import DataError, DeclarationError, FitError, RankDeficiencyError, StructSearchError
from .results import FitResult
from .separable import SeparableModel

__version__ = "0.1.0"
__all__ = ["SeparableModel", "FitResult", "StructSearchError", "DataError", "DeclarationError",
           "FitError", "RankDeficiencyError", "__version__"]
