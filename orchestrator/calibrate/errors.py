"""The one error of a calibration's bad input."""


class CalibrationError(ValueError):
    """Bad input found before any trial runs (a parameter, a range, the log); one line."""
