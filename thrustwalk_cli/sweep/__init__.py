"""The sweep engine: points from axes, task keys, executors and the resumable runner."""
