"""Deprecated alias of :mod:`structgen.domains.structures.render` (the structures domain's own module), for one release."""

from structgen._moved import moved

moved(__name__, "structgen.domains.structures.render")
