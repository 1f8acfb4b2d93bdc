"""CLI subcommands, one module each (see accelrig.cli)."""
