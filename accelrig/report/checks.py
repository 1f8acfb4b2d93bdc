"""What a result's checks say, in sentences: the one wording the TUI, the text reports and certificates use.

A result's ``quality`` holds figures (chi^2, dof, p, the noise found, what u is made of) keyed by what the
procedure measured; a person needs them read: whether the model fits, what the noise was, what u holds and
which local gravity the gains are scaled to.  ``check_lines`` reads them from the plain result (a
``CalibrationResult.to_json_dict()`` or a profile's), so a saved result says the same as the live one.
"""

from __future__ import annotations

import math

LACK_OF_FIT_ALPHA = 0.01   # the level every procedure's lack-of-fit test warns at (estimation.residuals.ALPHA)


def _lack_of_fit_sentence(chi2, dof, p) -> str:
    """chi^2 for dof (p) and what it means for the model."""
    if not dof or p is None or not math.isfinite(p):
        # no chi^2 printed: with no degrees of freedom it is rounding of the fit, not a figure
        return ("no degrees of freedom are left over once the model's unknowns are fitted, so the lack of fit "
                "cannot be tested (more poses or steps would test it)")
    verdict = ("the data disagree with the model beyond their noise (see the warnings)" if p < LACK_OF_FIT_ALPHA
               else "the data agree with the model within their noise")
    return f"χ² = {chi2:.3g} for {dof} degrees of freedom (p = {p:.3g}): {verdict}"


def _per_axis(value) -> str:
    """One figure, or three as x/y/z."""
    if isinstance(value, list) and len(value) == 3:
        return "x/y/z " + "/".join(f"{v:.3g}" for v in value)
    if isinstance(value, list):
        return ", ".join(f"{v:.3g}" for v in value)
    return f"{value:.3g}"


def _flexing_link_sentence(link: dict) -> str:
    """The slider-crank's flexing-link check: made or not (and why), and what it found."""
    if not link.get("made"):
        return (f"not checked: {link.get('why') or 'too few steps'}; a link or mounting that flexes would go unseen "
                "and its bias would not be in u (verify with more steady speed steps)")
    if not link.get("found"):
        return (f"checked over {link['steps']} steady steps: the harmonics keep the rigid crank's law, no flexing "
                "link or mounting seen")
    resonance = link.get("resonance_hz")
    seen = f"a resonance near {resonance:.0f} Hz" if resonance else "harmonics that shrink with speed"
    if link.get("ring_hz"):
        return (f"checked over {link['steps']} steady steps: {seen}, the link's ring at the dead centres (the "
                f"harmonics' trend alone: p = {link['p_value']:.1g}; see the warnings)")
    return (f"checked over {link['steps']} steady steps: {seen} (p = {link['p_value']:.1g}, see the warnings)")


def gravity_text(settings: dict) -> str:
    """The local gravity a result used, as every face prints it: g to 0.01 mm/s² (a value given, not
    estimated, so it keeps its digits) with its standard uncertainty."""
    return f"g = {settings['g']:.5f} ± {settings['g_u']:.2g} m/s²"


def check_lines(result: dict) -> list[tuple[str, str]]:
    """(what, sentence) for each check the result reports, in reading order; nothing for figures it lacks."""
    q = result.get("quality") or {}
    settings = result.get("settings") or {}
    lines = []
    source = q.get("uncertainty_source", q.get("uncertainty"))
    if isinstance(source, str) and source:
        lines.append(("uncertainty", source))
    coast = q.get("coast")
    if isinstance(coast, dict) and coast.get("note"):   # the wheel: the part of the record the fit used
        lines.append(("coast", str(coast["note"])))
    cross_axis = q.get("cross_axis")
    if isinstance(cross_axis, dict) and cross_axis.get("note"):   # the wheel: what its method cannot see
        lines.append(("cross-axis", str(cross_axis["note"])))
    tilt_p = q.get("tilt_p_value")
    if "chi2" in q and "dof" in q and q["chi2"] is not None:
        sentence = _lack_of_fit_sentence(q["chi2"], q["dof"], q.get("p_value"))
        if not q["dof"] and tilt_p is not None:   # the six-face model: its tilts carry the test instead
            sentence += "; the pose tilts below test the model instead"
        lines.append(("lack of fit", sentence))
    if tilt_p is not None and math.isfinite(tilt_p) and q.get("stated_flatness_deg"):
        within = ("beyond it: the flatness the tilts show is used instead (see the uncertainty)"
                  if tilt_p < LACK_OF_FIT_ALPHA else "within it")
        shown = q["stated_flatness_deg"] * math.sqrt(max(q["chi2_tilts"], 0.0) / q["tilt_dof"]) if q["tilt_dof"] else None
        if tilt_p >= LACK_OF_FIT_ALPHA and shown is not None and shown < 0.5 * q["stated_flatness_deg"]:
            # a first-time operator read "within it" as the data confirming the cross-axis u, and could not tell
            # why that u followed the number typed in, whatever the data
            within += (f"; the tilts the faces can show are about {shown:.2g} deg, yet the cross-axis terms' u "
                       "rests on the stated flatness: across gravity a pose's tilt and C's off-diagonal terms read "
                       "alike, so no data check it")
        lines.append(("pose tilts", f"the tilts the poses need to fit, against the stated flatness "
                                    f"{q['stated_flatness_deg']:g} deg: χ² = {q['chi2_tilts']:.3g} for "
                                    f"{q['tilt_dof']:.3g} degrees of freedom (p = {tilt_p:.3g}), {within}"))
    if q.get("radius_chi2") is not None and q.get("radius_dof"):
        lines.append(("steps agree", f"the radius of the steps: χ² = {q['radius_chi2']:.3g} for {q['radius_dof']} "
                                     f"degrees of freedom; the combined radius is stated with k = "
                                     f"{q.get('radius_k', 2):.3g}"))
    link = q.get("compliance_check")
    if isinstance(link, dict):
        lines.append(("flexing link", _flexing_link_sentence(link)))
    noise = q.get("noise")
    if isinstance(noise, dict) and noise.get("description"):
        lines.append(("noise", str(noise["description"])))
    sd = q.get("noise_sd_axes", q.get("noise_sd"))
    if sd is not None and q.get("residual_rms") is not None:
        lines.append(("residuals", f"rms {q['residual_rms']:.3g} m/s² against a noise sd of {_per_axis(sd)} m/s² "
                                   "(a model that holds leaves about the noise)"))
    if settings.get("g_u") is not None and settings.get("g") is not None:
        lines.append(("gravity", f"{gravity_text(settings)} ({settings.get('g_source') or 'as given'})"))
    missing = q.get("samples_missing")
    if missing:
        lines.append(("samples", f"{missing} samples missing from the record (see the warnings for what was done)"))
    return lines
