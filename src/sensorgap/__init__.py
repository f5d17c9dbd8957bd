"""sensorgap: sensor-coverage gaps of automated vehicles turned into test scenarios.

Pipeline (data flows one way): ``config`` -> ``models`` -> ``coverage`` -> ``roads`` ->
``analysis`` -> (search, export, report) with a thin ``cli`` on top.
"""

__version__ = "0.1.0"
