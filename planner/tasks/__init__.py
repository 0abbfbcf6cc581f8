"""Task suites (TOML under planner/problems/tasks/) and work cycles."""
