"""Built-in plugins (tracers, bases, converters), registered through the same entry points a third party uses."""
