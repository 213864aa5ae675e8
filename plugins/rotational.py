"""Built-in plugin (in progress): rotational."""
