"""What a calibration hands on: datasheets, exports to navigation stacks, the HTML report and figures."""

__all__: list[str] = []
