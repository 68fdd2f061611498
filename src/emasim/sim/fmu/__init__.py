"""pythonfmu slave scripts: each module is the main script of one FMU (built by emasim.sim.fmi).

pythonfmu copies a script into the FMU and the FMU imports it, by its file name, in the Python
of the process that loads the FMU; the scripts import emasim from there and read their
parameters from the JSON resource written beside them at export time.
"""
