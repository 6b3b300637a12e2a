"""Built-in problems. Each registers through the ``longtime.problems`` entry point group."""
