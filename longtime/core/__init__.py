"""The plugin contract and what runs a scheme: declared parameters, the problem and scheme bases,
the compiled drivers, the kernel cache, the registry of entry points."""
