"""The numbered blocks of the patent's block diagram (US 4,012,018, Fig. 1).

One module per block, each a small compiled function of (parameters, state,
inputs) with its reference numeral in the docstring; ``wiring`` says what
every switch S1-S19 connects, ``blocks`` lists every numeral. Together the
blocks are control electronics module 110 of the patent's vehicle drawing.
"""
