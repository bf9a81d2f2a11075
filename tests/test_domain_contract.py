"""The contract every registered domain keeps (built in or installed as a plugin), checked by the public
:func:`structgen.check_domain` for each one, and the checker itself shown to catch a broken domain.

A new domain gets these tests by registering. Each domain runs under its spec's ``test_settings``, which keep
evaluation to about a second.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from evolution.toys import Sphere
from structgen import check_domain, domains
from structgen.runs.domain_check import CHECKS, DomainContractError

SPECS = domains.specs()


@pytest.mark.parametrize("spec", SPECS, ids=[spec.id for spec in SPECS])
def test_every_registered_domain_keeps_the_contract(spec, tmp_path):
    report = check_domain(spec, folder=tmp_path)
    assert report.domain == spec.id and report.passed == CHECKS


class _Shaky(Sphere):
    """A sphere whose evaluation draws from a clock-seeded generator: not repeatable, and its measures leave their
    declared range."""

    def evaluate(self, genomes, seeds):
        result = super().evaluate(genomes, seeds)
        noise = np.random.default_rng().normal(size=len(result))
        return dataclasses.replace(result, objective=result.objective + noise, measures=result.measures + 1e6)


def test_the_checker_names_each_broken_rule_and_leaves_the_registry_as_it_was():
    shaky = domains.DomainSpec(
        id="shaky-v0", entry_point=f"{__name__}:_Shaky", settings="evolution.toys:SphereSettings", summary="broken on purpose"
    )
    with pytest.raises(DomainContractError) as caught:
        check_domain(shaky, skip=("resume",))
    failed = dict(caught.value.failures)
    assert {"determinism", "batch independence", "declared measures", "pickling"} <= set(failed)
    assert "objectives differ" in failed["determinism"] and "outside" in failed["declared measures"]
    assert "shaky-v0" in str(caught.value)
    assert "shaky-v0" not in {spec.id for spec in domains.specs()}  # registered only while it was checked
    with pytest.raises(ValueError, match="no check named"):
        check_domain("sphere-v0", skip=("speed",))
