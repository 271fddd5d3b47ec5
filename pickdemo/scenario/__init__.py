"""Scenario files: the schema (every key, validated), loading by name or path, the checks that
refuse a task that cannot succeed, the layout sampled from a seed, and the task as the robot is
told it."""
