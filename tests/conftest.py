"""What several test files share: the rule for tests that need the originals' reference data (see
:mod:`tests.reference`), and fixtures built by more than one file."""

from __future__ import annotations

import os

import pytest

from structgen.reference_data import reference_data
from tests.reference import FOLDERS, REQUIRE_VARIABLE, SKIP_REASON

_skipped_for_data: list[str] = []


def _required() -> bool:
    return bool(os.environ.get(REQUIRE_VARIABLE))


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--run-inductor",
        action="store_true",
        help="also run the tests marked inductor (torch.compile's code generation: minutes on a CPU; make test-all)",
    )


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if config.getoption("--run-inductor"):
        return
    skip = pytest.mark.skip(
        reason="torch.compile's code generation takes minutes on a CPU: make test-all (--run-inductor) runs it"
    )
    for item in items:
        if "inductor" in item.keywords:
            item.add_marker(skip)


def pytest_configure(config: pytest.Config) -> None:
    if _required() and not hasattr(config, "workerinput"):
        missing = [name for name in FOLDERS if reference_data(name) is None]
        if missing:
            raise pytest.UsageError(
                f"${REQUIRE_VARIABLE} is set but the reference data lacks {', '.join(name + '/' for name in missing)}"
            )


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    if report.skipped and SKIP_REASON in str(report.longrepr):
        _skipped_for_data.append(report.nodeid)


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    # Where the data is required (CI, which has it), a reference test that was skipped is a failure, not a pass.
    if _required() and _skipped_for_data and not hasattr(session.config, "workerinput"):
        reporter = session.config.pluginmanager.get_plugin("terminalreporter")
        if reporter is not None:
            reporter.write_line(f"{len(_skipped_for_data)} reference tests were skipped although ${REQUIRE_VARIABLE} is set:")
            for nodeid in _skipped_for_data[:20]:
                reporter.write_line(f"  {nodeid}")
        session.exitstatus = pytest.ExitCode.TESTS_FAILED
