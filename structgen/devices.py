"""Which torch device a name stands for, checked before any work: ``cpu``, ``cuda``, ``cuda:N`` or ``mps``.

A name is checked in two steps: its form (:func:`check_device_name`, without importing torch, so settings can check it
when they are read) and whether this machine has that device (:func:`resolve_device`, when the work starts). Either
refusal is an InputError naming the device, never a torch traceback.
"""

from __future__ import annotations

import re
from typing import Any

from structgen.errors import InputError

__all__ = ["DEVICE_NAMES", "check_device_name", "resolve_device"]

#: The device names structgen runs on.
DEVICE_NAMES = "cpu, cuda, cuda:N or mps"
_FORM = re.compile(r"cpu|cuda(:[0-9]{1,3})?|mps")


def check_device_name(name: Any, where: str = "device") -> str:
    """``name`` if it has the form of a device structgen runs on, else an InputError naming ``where``."""
    if not isinstance(name, str) or not _FORM.fullmatch(name):
        raise InputError(f"{where} = {name!r}: expected {DEVICE_NAMES}")
    return name


def resolve_device(name: Any, where: str = "device") -> Any:
    """The ``torch.device`` for ``name``, if this machine has it (a GPU that is not there is refused, not tried)."""
    import torch

    if isinstance(name, torch.device):
        name = str(name)
    check_device_name(name, where)
    device = torch.device(name)
    if device.type == "cuda":
        count = torch.cuda.device_count() if torch.cuda.is_available() else 0
        if count == 0:
            raise InputError(f"{where} = {name!r}: this machine has no CUDA device (torch {torch.__version__})")
        if device.index is not None and device.index >= count:
            raise InputError(f"{where} = {name!r}: this machine has {count} CUDA device(s), numbered from 0")
    if device.type == "mps" and not torch.backends.mps.is_available():
        raise InputError(f"{where} = {name!r}: this machine has no Apple GPU (mps)")
    return device
