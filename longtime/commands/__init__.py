"""The command line: one module per command, argument parsing, the entry point main."""
