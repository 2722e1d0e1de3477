"""Headless subcommands of the command line, one module each. No Qt."""
