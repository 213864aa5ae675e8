"""Built-in plugin (in progress): coupled_inductors."""
