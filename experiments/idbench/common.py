"""Strata, method names and settings shared by the benchmark's modules, and the stop flag that
Ctrl-C sets (every long loop calls check_stop)."""
import os
import threading

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

RATIO_STRATA = ["r<0.01", "0.01<=r<0.1", "r>=0.1"]
RATIO_DECADE = {"r<0.01": (-3.0, -2.0), "0.01<=r<0.1": (-2.0, -1.0), "r>=0.1": (-1.0, 0.0)}
UNITS_STRATA = ["natural", "units"]
SHAPE_STRATA = ["long", "few", "many"]
STEPS_STRATA = ["regular", "irregular", "gaps"]
SIGMA_STRATA = [0.0, 1e-3, 1e-2, 5e-2]
METHODS = ["csympnet", "csympnet_library", "csympnet_positions", "csympnet_differenced", "sindy",
           "oracle"]
CORE_CHOICE_METHODS = ["csympnet", "csympnet_library"]  # the core-choice table
LIBRARY_MAX_D = 10  # csympnet_library runs up to this d (the library core's default limit)
VIOLATION_STRATA = ["nonuniform-1.5", "nonuniform-3", "nonuniform-30", "coulomb-0.2",
                    "coulomb-0.5", "coulomb-0.9", "quadratic-drag", "periodic-force",
                    "drifting-equilibrium", "energy-gain"]
CHECK_NAMES = ["measured_momenta", "dissipation", "linear_damping", "one_rate", "residuals"]
VERDICTS = ["identified", "not identified", "rejected", "failed"]

GEN_OMEGA_DT = 1e-3      # omega_max * RK4 substep when generating data


class Interrupted(Exception):
    pass


STOP = threading.Event()


def check_stop():
    if STOP.is_set():
        raise Interrupted()


# The kind of dissipation term of fit's report ("dissipation" terms) that identifies each
# violation family's extra dissipation.
NAMED_DISSIPATION = {"coulomb": "coulomb", "quadratic-drag": "drag"}


def violation_reference(v, kinds):
    """(gamma, (low, high)) an answer on a violation case is judged against: the drawn
    gamma_reference and its range, or, where the answer names the family's own dissipation term
    (dry friction, drag: `kinds` from fit's report), the viscous part alone, which is then what
    its gamma means."""
    named = NAMED_DISSIPATION.get(v.get("family"))
    if named is not None and named in (kinds or []) and v.get("gamma_viscous") is not None:
        g = v["gamma_viscous"]
        return g, (g, g)
    return v["gamma_reference"], tuple(v["gamma_reference_range"])
