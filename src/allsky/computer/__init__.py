"""Computer 111: CPU 22, word registers 23 and 24, computer sequencer 21.

Also the ground program that computes the programmed angles held in
register 24 (``targeting``).
"""
