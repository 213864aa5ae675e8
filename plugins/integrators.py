"""Built-in plugin (in progress): integrators."""
