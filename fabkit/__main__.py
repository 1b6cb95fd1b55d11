"""``python -m fabkit``: the same command line as the ``fabkit`` script."""

from .cli import entry

if __name__ == "__main__":  # imported (e.g. by pytest's doctest collection), it does nothing
    entry()
