"""Master sequencer 20: the mode table, the mode rules, the watch and the plans.

The patent's plan (Modes 1 to 6-2) and the dither comparison plan.
"""
