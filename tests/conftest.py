"""Test settings shared by every test module.

Property-based tests (hypothesis) draw parameters over decades; they run
without a deadline (symbolic work varies in time, and tests assert nothing
about wall time) and, under CI, derandomized so a run can be repeated.
"""

import os
import types

import pytest
from hypothesis import HealthCheck, settings

import lagrangian as lg

settings.register_profile(
    "default",
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.differing_executors],
)
settings.register_profile("ci", parent=settings.get_profile("default"), derandomize=True, print_blob=True)
settings.load_profile("ci" if os.environ.get("CI") else "default")


@pytest.fixture
def registry_with():
    """``registry_with(Component, ...)``: a registry with the installed plugins and one more, registered in-process,
    providing the given component classes (a plugin a test writes)."""
    def build(*classes):
        plugin = types.ModuleType("test_plugin")

        @lg.hookimpl
        def register_component_types(register):
            for cls in classes:
                register(cls)

        plugin.register_component_types = register_component_types
        return lg.Registry(plugins={"test_plugin": plugin})

    return build


#: Modules whose tests run subprocesses, ngspice, clusters or long property searches: `make test-fast` skips them,
#: every test named for ngspice, and the tests marked ``@pytest.mark.slow`` one by one (those that take more than
#: about half a second: examples, processes, derivations checked against another engine); `make test` and CI run
#: everything.
SLOW_MODULES = {"test_examples", "test_sweep_dask", "test_transducer_spice", "test_fuzz", "test_robustness",
                "test_ngspice", "test_spatial_chains", "test_untrusted_code", "test_compare_params", "test_site",
                "test_notebook"}


def pytest_collection_modifyitems(config, items):
    for item in items:
        module = item.nodeid.split("::")[0].rsplit("/", 1)[-1].removesuffix(".py")
        if module in SLOW_MODULES or "ngspice" in item.name:
            item.add_marker(pytest.mark.slow)
