"""physics: judge lattice structures under gravity (breakable-joint rigid bodies in headless PyBullet).

A library of its own: it takes anything that offers ``vertices`` and ``edges`` arrays and imports nothing from
``structgen``. The stability checks arrive with issue 3.
"""
