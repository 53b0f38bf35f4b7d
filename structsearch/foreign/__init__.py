"""A simulator no one here wrote: a JSBSim aircraft (one of JSBSim's own, or any aircraft directory) evaluated at
recorded states term by term (:mod:`.evaluate`), as the baseline of ``diagnose --simulator jsbsim:...``
(:mod:`.baseline`). Its aircraft file is read as data (:mod:`.aircraft_xml`), never run, and loaded by JSBSim from
a private copy whose aerodynamics read what the recording gives (:mod:`.private_copy`)."""
