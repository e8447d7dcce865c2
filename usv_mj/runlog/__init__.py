"""Every run logged to MCAP: a streaming writer, a reader, and ``usv-mj inspect``.

Public API::

    from usv_mj.runlog import RunLogWriter, read_run, load_topic
    with RunLogWriter("run.mcap", scenario) as writer:
        record = simulate(scenario, sinks=[writer.sink("main")])
    log = read_run("run.mcap")          # log.record, log.baseline, log.metadata, log.attachments, log.topics()
    state = load_topic("run.mcap", "/usv/state")   # {"log_time": ..., "t": ..., "x": ..., ...}

Topics, schemas and number conventions: :mod:`usv_mj.runlog.topics`.
"""

from .inspect_cli import add_inspect_arguments, inspect_command
from .reader import RunLog, RunLogReadError, load_topic, read_run, scan_summary
from .topics import ROW_TOPICS, SCHEMA_VERSION, WORLD_FRAME, frame_for, prefix_for, reference_frame_for, row_topics, topic_table
from .writer import RunLogError, RunLogSink, RunLogWriter

__all__ = ["RunLogWriter", "RunLogSink", "RunLogError", "read_run", "load_topic", "scan_summary", "RunLog",
           "RunLogReadError", "add_inspect_arguments", "inspect_command", "ROW_TOPICS", "SCHEMA_VERSION",
           "prefix_for", "frame_for", "reference_frame_for", "row_topics", "topic_table", "WORLD_FRAME"]
