"""Local planning: the potential fields and the controllers that turn a plan into (v, omega)."""
