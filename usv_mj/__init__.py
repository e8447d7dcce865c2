"""usv_mj: the paper's adaptive prescribed-performance USV controller on an analytic and a MuJoCo plant.

Python API (see the README)::

    from usv_mj import load_scenario, simulate, summarize
    scenario = load_scenario(preset="paper", overrides={"duration": 60.0})
    record = simulate(scenario)
    print(summarize(record)["errors_at"])

The names below are imported on first use, so that ``usv_mj.ship`` (the physics, which the
controllers use) can be imported without the rest of the package.
"""

from importlib import import_module

__version__ = "0.1.0"

_API = {
    "RunRecord": "usv_mj.record",
    "Scenario": "usv_mj.scenario",
    "ScenarioError": "usv_mj.scenario",
    "load_scenario": "usv_mj.scenario",
    "simulate": "usv_mj.simulation",
    "summarize": "usv_mj.summary",
    "run_job": "usv_mj.main_job",
}
__all__ = [*_API, "__version__"]


def __getattr__(name):
    if name in _API:
        return getattr(import_module(_API[name]), name)
    raise AttributeError(f"module 'usv_mj' has no attribute {name!r}")
