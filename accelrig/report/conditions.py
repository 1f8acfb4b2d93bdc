"""Who a certificate is for and who issues it: the conditions ``accelrig report`` takes as flags
(--number, --customer, --customer-reference, --operator, --approved-by, --location, --temperature,
--humidity), declared as
settings so the TUI's certificate form asks for the same fields in the same words."""

from __future__ import annotations

from accelrig.settings import Setting

CONDITION_SETTINGS = (
    # each certificate has its own number: not offered again to the next one
    Setting("number", "certificate number", kind="text", remembered=False),
    Setting("customer", "customer (name and address)", kind="text"),
    # the customer's order is this certificate's: not offered again either
    Setting("customer_reference", "the customer's reference or order number, printed under the customer",
            kind="text", remembered=False, label="customer's reference or order number"),
    Setting("operator", "who performed the calibration", kind="text"),
    Setting("approved_by", "who authorises the certificate (printed above the signature line; without it the "
            "name is left blank to fill in by hand)", kind="text", label="who authorises the certificate"),
    Setting("location", "where it was performed", kind="text"),
    Setting("temperature", "ambient temperature, e.g. '23.0 ± 1.0 °C' (a bare number is in °C)", kind="text"),
    Setting("humidity", "relative humidity, e.g. '45 ± 10 %' (a bare number is in %)", kind="text"),
)

# a setting's name -> the certificate's condition (the number is the certificate's, the rest are the same word)
CONDITION_KEYS = {"number": "certificate_number"}


def conditions_from_values(values: dict) -> dict:
    """The certificate's conditions (render_html's ``conditions``) from the settings' values."""
    return {CONDITION_KEYS.get(name, name): value for name, value in values.items()}
