"""The thin command-line layer behind the ``brdflab`` command (no rendering logic here)."""
