"""The files that drive studies and keep their results: the sweep configuration, the fit's
files, summary and runner. Imports studies and below."""
