"""An example longtime plugin (docs/plugins.md): a pendulum and three schemes."""
