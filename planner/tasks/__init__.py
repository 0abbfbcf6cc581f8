"""Task suites (TOML under problems/tasks/) and work cycles."""
