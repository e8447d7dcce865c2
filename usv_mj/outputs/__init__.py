"""Outputs: figures, report, video, the MCAP log and output folders, made from a finished record and its statics only."""
