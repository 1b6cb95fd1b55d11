"""The design's verdict in words a maker acts on (pure data, nothing drawn).

The verdict (the worst of the as-built checks, the motion and the tolerance analysis) is known
only once the export has checked its files; the guide's first page and the head of the bill of
materials are then made again with it (the batch engine's report stage hands it over as data:
``level``, ``text`` and ``findings``, as report.json's ``verdict`` has them). Every sentence is
given whole: the pages wrap it between words, never inside one.
"""

from __future__ import annotations

__all__ = ["verdict_rows", "NOT_JUDGED", "WATCH_JOINTS"]

#: The level of a guide made without a verdict (the writers alone, outside ``fabkit export``).
NOT_JUDGED = "not judged"
#: Joints named for the maker to watch: the deepest stacks, where play adds up.
WATCH_JOINTS = 5

_EXPECT = {
    "ok": "the kit should move as the motion test describes, within the distances it gives.",
    "by design": "the far end will not land where the design puts it in every build: that is "
                 "what this design shows (the report says why); the test pages give the design's "
                 "own numbers.",
    "FAIL": "do not cut yet: the files did not pass their own check (report.md names the "
            "file and the check).",
}
_ADJUST = {
    "ok": "nothing beyond the usual: cut the test coupon first and set the shims for your "
          "measured sheet (the guide's 'Your sheet').",
    "FAIL": "export again once what report.md names is fixed; these sheets may not rebuild the "
            "design.",
}
_ADJUST_FLAG = ("cut the test coupon first and take the hole that fits the post with the least "
                "wobble (laser_coupon.md); measure the sheet and set the shims as 'Your sheet' says; "
                "close every screw snug, not tight. If the test stops short, loosen the screws "
                "named below a quarter turn before you force anything.")


def _watch(plan) -> str:
    """The deepest stacks (and the joints that take a clevis pin), deepest first."""
    joints = sorted(plan.stacking.joints, key=lambda js: (-len(js.layers), js.joint))
    out = []
    for js in joints[:WATCH_JOINTS]:
        kind = getattr(js.fastener, "kind", "")
        out.append(f"J{js.joint} ({len(js.layers)} bars" + (", clevis pin" if kind == "clevis pin"
                                                            else "") + ")")
    return ", ".join(out)


def _expect_flag(findings: list) -> str:
    about = {f.get("about") for f in findings if f.get("level") == "FLAG"}
    if "motion" in about:
        return ("the design itself does not reach its designed end: the motion test shows where "
                "it stops; do not expect more from the kit.")
    return ("not every build of a laser kit behaves as designed with the errors of cutting and "
            "play: yours may stop short or move a port the design keeps still. Measure the "
            "test pages' distances and compare.")


def verdict_rows(verdict: dict | None, plan) -> list:
    """The verdict, what to expect, what to adjust and which joints to watch, one row each.

    Parameters
    ----------
    verdict : dict or None
        ``level``, ``text`` and ``findings`` (:meth:`fabkit.pipeline.Verdict.as_dict`); None
        for a guide made outside ``fabkit export`` (no checks ran).
    plan : fabkit.fab.laser_plan.LaserPlan

    Returns
    -------
    list of str
        Whole sentences, never shortened.
    """
    watch = _watch(plan)
    if verdict is None:
        return [f"Verdict: {NOT_JUDGED}. These files were made without the export's checks and "
                "tolerance analysis; `fabkit export` judges the design and writes its verdict "
                "here and at the head of report.md.",
                f"Which joints: the deepest stacks, {watch}: check that they turn freely before "
                "you go on."]
    level = str(verdict.get("level", ""))
    text = str(verdict.get("text", ""))
    findings = list(verdict.get("findings", []))
    expect = _EXPECT.get(level) or _expect_flag(findings)
    adjust = _ADJUST.get(level, _ADJUST_FLAG)
    return [f"Verdict: {level}. {text[:1].upper()}{text[1:]}",
            f"What to expect: {expect}",
            f"What to adjust: {adjust}",
            f"Which joints: the deepest stacks, where play adds up: {watch}. Check that each "
            "turns freely when its page is done."]
