"""Command line interface (placeholder until the CLI module lands)."""


def main():  # pragma: no cover
    raise SystemExit("softrod CLI not built yet")
