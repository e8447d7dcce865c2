"""usv_mj: the paper's adaptive prescribed-performance USV controller on an analytic and a MuJoCo plant.

Python API (see the README)::

    from usv_mj import load_scenario, simulate, summarize
    scenario = load_scenario(preset="paper", overrides={"duration": 60.0})
    record = simulate(scenario)
    print(summarize(record)["errors_at"])
"""

from .record import RunRecord
from .scenario import Scenario, ScenarioError, load_scenario
from .simulation import simulate
from .summary import summarize

__version__ = "0.1.0"
__all__ = ["RunRecord", "Scenario", "ScenarioError", "load_scenario", "simulate", "summarize", "__version__"]
