"""Front ends: the command line, step display, reports, figures and generated docs.

Everything that prints, draws or writes files for a user lives here.
"""
