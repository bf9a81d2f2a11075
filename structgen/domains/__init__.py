"""Domains: what structgen can evolve, each binding a generator to a judge as an :class:`evolution.Problem`.

Each domain lives in its own package here (``structures/``; the toy problems in ``toys/``) and is registered by one
line in :data:`registry.BUILTIN`; other packages register theirs through the ``structgen.domains`` entry-point group.
Domains import neither each other nor the command line; what two domains share sits one level up, in ``structgen``.

>>> from structgen import domains
>>> [d.id for d in domains.specs()][:1]
['structures-v0']
>>> problem = domains.make("structures-v0")      # the problem with default settings
"""

from structgen import registry as _registry
from structgen.registry import *  # noqa: F403  (the registry's public names are this package's)

__all__ = list(_registry.__all__)
