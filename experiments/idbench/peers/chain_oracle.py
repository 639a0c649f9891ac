"""The two-mass friction records' oracle (idbench/friction_chain.py): the true form given to
`csympnet fit`, fitted by the same route as csympnet's own fit, with no selection.

The true form is a quadratic potential with dry friction on each mass:

    --core {"type": "library", "terms": ["q1", "q2", "q1^2", "q2^2", "(q1-q2)^2"],
            "dissipation": ["coulomb(p1)", "coulomb(p2)"]}

(the linear terms because the library's terms are centred on the data's mean, not on the
equilibrium; q1^2, q2^2 and (q1-q2)^2 span every quadratic form). The inverse mass matrix is
still learned, as it always is in the library core, so the form is the truth's and slightly
more. What this oracle shows is what csympnet's selection costs: the potential's terms and
the dissipation chosen from the data against given. It is not an independent fit (the 1-dof
strata's oracle, peers/friction_oracle.py, is one); least squares through the exact chain
simulator over 22 unknowns would take minutes a record.
"""
import json

CHAIN_CORE = {"type": "library", "terms": ["q1", "q2", "q1^2", "q2^2", "(q1-q2)^2"],
              "dissipation": ["coulomb(p1)", "coulomb(p2)"]}


def chain_oracle_arguments(extra):
    """`fit`'s options for the oracle: the caller's, less any --core or --dissipation, and the
    true form"""
    out, skip = [], False
    for a in extra:
        if skip:
            skip = False
            continue
        if a in ("--core", "--dissipation"):
            skip = True
            continue
        if a.startswith("--core=") or a.startswith("--dissipation="):
            continue
        out.append(a)
    return out + ["--core", json.dumps(CHAIN_CORE)]
