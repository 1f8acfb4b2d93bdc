"""Built-in accelrig driver plugins (installed as ``accelrig_drivers``).

Each module defines one Driver subclass and is registered in pyproject.toml
under the ``accelrig.drivers`` entry-point group, exactly as a third-party
plugin would be.
"""
