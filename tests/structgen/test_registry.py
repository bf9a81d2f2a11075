"""The domain registry's own services (the per-domain contract is tests/test_domain_contract.py)."""

from __future__ import annotations

import pytest

from structgen import domains

COMPILED: list[str] = []


def compile_for_test() -> None:
    COMPILED.append("compiled")


def test_install_compiles_each_domains_kernels_once_even_when_domains_share_them(monkeypatch):
    from structgen import registry

    # The built-in domains with numba code: warehouse and manufacturing share the planners' kernels.
    built_in = {spec.id: spec.kernels for spec in domains.specs()}
    assert built_in["warehouse-v0"] == built_in["manufacturing-v0"] is not None
    assert built_in["autoverse-v0"] and built_in["fortress-v0"]
    shared = f"{__name__}:compile_for_test"
    fakes = {
        name: domains.DomainSpec(id=name, entry_point="m:p", settings="m:s", summary="s", kernels=kernels)
        for name, kernels in (("one-v0", shared), ("two-v0", shared), ("three-v0", None))
    }
    monkeypatch.setattr(registry, "_registry", fakes)
    monkeypatch.setattr(registry, "_loaded", True)
    COMPILED.clear()
    assert registry.compile_kernels() == [registry.OPTIMIZER_KERNELS, shared] and COMPILED == ["compiled"]
    with pytest.raises(ValueError, match="kernels"):
        domains.DomainSpec(id="bad-v0", entry_point="m:p", settings="m:s", summary="s", kernels="no_colon")
