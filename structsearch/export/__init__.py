"""An identified model handed to a simulator: a self-contained model card (``model.json``), JSBSim aerodynamics
and separation-state systems with an example aircraft, and the check that JSBSim computes what structsearch
computes (docs/interfaces.md 7.6).

The package renders what the API fitted (it fits nothing itself): :mod:`.card` is the exported model as a typed
record and its JSON, :mod:`.xml_functions` maps a regressor of the expression grammar onto JSBSim's function
XML, :mod:`.jsbsim_files` writes the aerodynamics and the states' system, :mod:`.aircraft` the example
aircraft and its stall script, :mod:`.check` drives the real JSBSim library with recorded inputs.
"""
