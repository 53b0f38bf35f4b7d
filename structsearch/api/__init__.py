"""The public Python API: what each command does, as typed functions (docs/interfaces.md 6.1).

=====================================  ==============================================
``structsearch fit --model CD-IXr``    :func:`fit` -> :class:`FitOutcome`
``structsearch fit --joint CL-VI,...`` :func:`fit_joint` -> JointFit
``structsearch search --grid drag``    :func:`search` -> :class:`Ranking`
``structsearch diagnose --model CD-I`` :func:`diagnose` -> Diagnosis
``structsearch discover --coefficient`` :func:`discover` -> Discovery
``structsearch simulate``              :func:`simulate` -> Campaign
``structsearch preprocess``            :func:`preprocess` -> :class:`PreprocessOutcome`
``structsearch study``                 :func:`study` -> :class:`StudyOutcome`
``structsearch report``                :func:`report` -> :class:`ReportOutcome`
``structsearch demo``                  :func:`structsearch.workflows.demo`
``structsearch compare A B``           :func:`compare_outputs` -> OutputComparison
``structsearch export --format jsbsim`` :func:`export` -> :class:`ExportOutcome`
=====================================  ==============================================
"""
from ..experiments.reproducibility import OutputComparison, Tolerances, compare_outputs
from .commands import diagnose, fit, fit_joint, preprocess, search, simulate, study
from .discovering import discover
from .exporting import ExportOutcome, export
from .report import report
from .results import FitOutcome, PreprocessOutcome, Ranking, ReportOutcome, StudyOutcome
from .settings import FlightTestPlan, Settings

__all__ = ["ExportOutcome", "export", "FitOutcome", "FlightTestPlan", "Settings", "OutputComparison", "Tolerances", "compare_outputs", "PreprocessOutcome", "Ranking", "ReportOutcome", "StudyOutcome", "diagnose", "discover", "fit",
           "fit_joint", "preprocess", "report", "search", "simulate", "study"]
