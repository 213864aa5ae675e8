"""Built-in plugin (in progress): transducers."""
