"""The benchmark: planning methods judged side by side by evaluate()."""
