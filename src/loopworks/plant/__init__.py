"""Plant models: processes, valves, sensors. They are blocks too."""
