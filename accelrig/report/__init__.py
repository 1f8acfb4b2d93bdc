"""Calibration certificates: HTML (inline SVG figures), PDF through headless Chromium.

``load_source`` reads a profile, a saved result or a campaign; ``from_result`` wraps a result in memory;
``certificate_html`` renders; ``write_certificate`` writes .html or .pdf atomically.  matplotlib (the
``report`` extra) is imported only when figures are drawn.
"""

from accelrig.report.certificate import certificate_html, write_certificate
from accelrig.report.source import Source, from_result, load_source

__all__ = ["Source", "certificate_html", "from_result", "load_source", "write_certificate"]
