"""Deprecated alias of :mod:`structgen.domains.structures.tall` (the structures domain's own module), for one release."""

from structgen._moved import moved

moved(__name__, "structgen.domains.structures.tall")
