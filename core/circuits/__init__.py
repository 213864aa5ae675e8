"""The circuit bridge: analogies between domains, SPICE decks and ngspice runs, netlists read in, comparisons
with ngspice.
"""
