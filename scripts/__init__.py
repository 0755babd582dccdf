"""The command-line front ends: one module per `frictiongym` subcommand (cli.py dispatches), each a thin
argument parser over functions of frictiongym.agents; `python scripts/<name>.py` runs the same."""
