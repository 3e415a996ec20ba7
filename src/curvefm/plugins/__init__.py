"""Built-in plugins (tracers, bases, converters, map methods), registered through the same entry points a third
party uses."""
