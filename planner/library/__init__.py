"""Feed-forward trajectory libraries: build, store, export, query."""
