"""Every run logged to MCAP: a streaming writer and a reader (``usv-mj inspect``: :mod:`usv_mj.cli.inspect`).

Public API::

    from usv_mj.outputs.log import RunLogWriter, read_run, load_topic
    with RunLogWriter("run.mcap", scenario) as writer:
        record = simulate(scenario, sinks=[writer.sink("main")])
    log = read_run("run.mcap")          # log.record, log.baseline, log.metadata, log.attachments, log.topics()
    state = load_topic("run.mcap", "/usv/state")   # {"log_time": ..., "t": ..., "x": ..., ...}

Topics, schemas and number conventions: :mod:`usv_mj.outputs.log.topics`.
"""

from usv_mj.core.lazy_names import lazy_names

# imported on first use: the log writer's process needs the writer, not the reader (numba) nor
# the inspect command
__getattr__, __dir__, __all__ = lazy_names(__name__, {
    "RunLog": ".reader", "RunLogReadError": ".reader", "load_topic": ".reader", "read_run": ".reader",
    "scan_summary": ".reader",
    "ROW_TOPICS": ".topics", "SCHEMA_VERSION": ".topics", "WORLD_FRAME": ".topics", "frame_for": ".topics",
    "prefix_for": ".topics", "reference_frame_for": ".topics", "row_topics": ".topics", "topic_table": ".topics",
    "RunLogError": ".writer", "RunLogSink": ".writer", "RunLogWriter": ".writer",
})
