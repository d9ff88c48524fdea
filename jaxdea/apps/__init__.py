"""Applications: the command line, the paper's figures and their style, the interactive
explorer. Imports anything below."""
