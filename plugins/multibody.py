"""Built-in plugin (in progress): rigid bodies and joints."""
