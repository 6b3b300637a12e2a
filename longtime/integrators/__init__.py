"""Built-in schemes. Each registers through the ``longtime.integrators`` entry point group."""
