"""Hardware as sold: Chicago screws and their extensions, clevis pins, washers, split pins.

One catalogue chooses the fastener of every joint of a laser kit and names each part the way a
shop lists it (series, barrel, post length, material), so that the bill of materials can be
ordered as it stands.

* **Chicago screws** (sex bolts, binding posts, book screws): a barrel with a female thread, a
  screw with a male one; the barrel is the pin the bars turn on, and vendors name a screw by
  its post (barrel) length, not by its diameter ("1/4 in" is a length). The default is the
  metric book screw sold most widely, M4 thread on a 5 mm barrel with 10 mm heads; inch kits
  take the US binding post (#8-32 thread, 3/16 in barrel, 3/8 in heads, posts 1/8-2 in,
  aluminium) with its screw-on extensions (1/4-1 in). Smaller (M3, 4 mm barrel) and larger
  (M5, 6 mm) metric series are listed too. Each entry names the product family it follows
  (:attr:`ScrewSpec.family`).
* **Deep stacks** (more sheets than the longest post holds): inch posts take up to
  :data:`MAX_EXTENSIONS` screw-on extensions, which keep the heads of the post; a metric joint
  gets a clevis pin of the barrel's diameter (ISO 2341 B: the bars turn on its plain shank),
  a washer and a split pin, with shims taking up the play. Both stand no taller above the
  stack than a Chicago screw's head and its shims, which is what the stacking reserves above
  and below every screw (bars sweep over the joints of a deep kit). A bolt with a lock nut
  and spacers would hold the stack too, but its thread and nut stand 10-20 mm proud of it.
* **Axial play**: the post closes on the thickest sheets the tolerance allows; shim rings
  (DIN 988, made to slide on a shaft of their inner diameter: 0.5 mm, and a 0.2 mm one where
  the play would be more than half a millimetre) under the head take up the rest on the
  nominal sheet, to at most
  :data:`MAX_AXIAL_PLAY`. On thicker sheet some come off (:attr:`Fastener.play_min` is the
  play then), on thinner sheet the spares go on.
* **Washers** are chosen by inner diameter: a flat washer over a barrel or a pin clears it
  (an M3 washer's 3.2 mm hole does not go over a 4.0 mm barrel; a DIN 433 M4 washer, 4.3 mm,
  does).

Sizes are typical catalogue values; parts differ between makers by a few tenths of a
millimetre, so measure what you bought and override the entry (``laser.screw`` as a table).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, fields, replace
from fractions import Fraction

from ..errors import FabricationError
from ..numerics import MM_SLACK
from ..io.schema import ScrewSection, check_table

__all__ = ["ScrewSpec", "CATALOGUE", "DEFAULT_SCREW", "screw_spec", "choose_length",
           "WASHER_THICKNESS", "WASHER_CLEARANCE", "Washer", "WASHERS", "MAX_AXIAL_PLAY",
           "choose_washer", "PinSpec", "PINS", "Fastener", "fit_fastener", "PartLine",
           "merge_parts", "inch_text", "MM_PER_INCH", "MAX_EXTENSIONS"]

#: Thickness of the thin washers (shims) the metric entries take up axial play with (mm).
WASHER_THICKNESS = 0.5
#: Most axial play a joint's shims leave on sheet of the nominal thickness (mm): the bars turn
#: freely and the stack does not rattle.
MAX_AXIAL_PLAY = 0.5
#: The play a thin shim is added above (mm): a tenth inside the limit, so round-off of the
#: sheet's nominal thickness never tips a joint over it.
_PLAY_TARGET = MAX_AXIAL_PLAY - 0.1
#: A washer over a barrel or a shank must clear it by at least this much (mm): the barrel's
#: tolerance is negative, a washer's hole positive, and a tight fit binds the turning bar.
WASHER_CLEARANCE = 0.2
MM_PER_INCH = 25.4
#: Most screw-on extensions stacked on one post.
MAX_EXTENSIONS = 3


def inch_text(mm: float) -> str:
    """A length in mm as the inch fraction a shop lists (to 1/64 in): ``"1 1/4 in"``.

    Examples
    --------
    >>> inch_text(31.75), inch_text(4.7625)
    ('1 1/4 in', '3/16 in')
    """
    q = Fraction(round(mm / MM_PER_INCH * 64), 64)
    whole, rest = divmod(q, 1)
    parts = ([str(whole)] if whole else []) + ([f"{rest.numerator}/{rest.denominator}"]
                                               if rest else [])
    return " ".join(parts or ["0"]) + " in"


def _inch(*values) -> tuple[float, ...]:
    return tuple(float(Fraction(v) * Fraction(254, 10)) for v in values)


@dataclass(frozen=True)
class Washer:
    """A flat washer as sold (mm).

    Attributes
    ----------
    name : str
        Catalogue key, e.g. ``"DIN 433 M4"``; it starts with the standard the washer follows.
    inner, outer, thickness : float
    material : str
    unit : str
        ``"mm"`` or ``"in"`` (how the shop states its sizes).
    shim : bool
        A shim ring (DIN 988), made to slide on a shaft of its inner diameter, rather than a
        flat washer with a clearance hole.
    """

    name: str
    inner: float
    outer: float
    thickness: float
    material: str = "stainless steel A2"
    unit: str = "mm"
    shim: bool = False

    def description(self) -> str:
        if self.shim and self.unit == "in":
            return (f"precision {self.name} ({self.inner:.2f} x {self.outer:.2f} x "
                    f"{self.thickness:.2f} mm), {self.material}")
        if self.shim:
            return (f"shim ring {self.name} ({self.inner:g} mm ID x {self.outer:g} mm OD x "
                    f"{self.thickness:g} mm), {self.material}")
        if self.unit == "in":
            return (f"flat washer {self.name}: {self.inner / MM_PER_INCH:.3f} in ID x "
                    f"{self.outer / MM_PER_INCH:.3f} in OD x {self.thickness / MM_PER_INCH:.3f} "
                    f"in ({self.inner:.2f} x {self.outer:.2f} x {self.thickness:.2f} mm), "
                    f"{self.material}")
        return (f"washer {self.name}: {self.inner:g} mm ID x {self.outer:g} mm OD x "
                f"{self.thickness:g} mm, {self.material}")


#: Flat washers: DIN 433 (small outer diameter, thin) and ISO 7089 (normal series), metric;
#: SAE flat washers, inch.
WASHERS: dict[str, Washer] = {w.name: w for w in (
    Washer("DIN 433 M3", 3.2, 6.0, 0.5),
    Washer("DIN 433 M4", 4.3, 8.0, 0.5),
    Washer("DIN 433 M5", 5.3, 9.0, 1.0),
    Washer("DIN 433 M6", 6.4, 11.0, 1.6),
    Washer("ISO 7089 M3", 3.2, 7.0, 0.5),
    Washer("ISO 7089 M4", 4.3, 9.0, 0.8),
    Washer("ISO 7089 M5", 5.3, 10.0, 1.0),
    Washer("ISO 7089 M6", 6.4, 12.0, 1.6),
    Washer("SAE #10", *_inch("0.219", "0.5", "0.049"), material="steel, zinc-plated",
           unit="in"),
    *(Washer(f"DIN 988 {d:g}x{o:g}x{t:g}", d, o, t, material="spring steel", shim=True)
      for d, o in ((4.0, 8.0), (5.0, 10.0), (6.0, 12.0)) for t in (0.5, 0.2)),
    # precision shim washers for a 3/16 in shaft, 3/8 in outside (under a 3/8 in head)
    *(Washer(f"shim 3/16 x 3/8 x {t} in", *_inch("0.194", "0.375", t), material="steel",
             unit="in", shim=True) for t in ("0.020", "0.008")),
)}


def choose_washer(shaft: float, *, outer_max: float | None = None, family: str = "DIN 433",
                  unit: str = "mm") -> Washer:
    """The catalogue washer of ``family`` with the smallest hole that clears ``shaft`` by
    :data:`WASHER_CLEARANCE` (and an outer diameter within ``outer_max``).

    Raises
    ------
    FabricationError
        No washer of the catalogue fits.

    Examples
    --------
    >>> choose_washer(4.0).name          # a 4.0 mm barrel: not the M3 washer (3.2 mm hole)
    'DIN 433 M4'
    """
    fits = [w for w in WASHERS.values()
            if not w.shim and w.inner >= shaft + WASHER_CLEARANCE - MM_SLACK and w.unit == unit
            and (unit == "in" or w.name.startswith(family))
            and (outer_max is None or w.outer <= outer_max + MM_SLACK)]
    if not fits:
        raise FabricationError(f"no {family} washer of the catalogue goes over a {shaft:g} mm "
                               f"shaft with {WASHER_CLEARANCE:g} mm clearance")
    return min(fits, key=lambda w: (w.inner, w.thickness))


@dataclass(frozen=True)
class PinSpec:
    """A clevis pin series for deep stacks (ISO 2341 B: a head, a plain shank and a hole for
    a split pin), with the washer and split pin that go with it.

    Attributes
    ----------
    name : str
        ``"4-pin"``.
    diameter : float
        Shank diameter (mm): the pin the bars turn on.
    head_diameter, head_height : float
    lengths : tuple of float
        Lengths sold (mm, under the head).
    hole_to_end : float
        Distance from the split-pin hole's centre to the pin's end (mm).
    split_pin : float
        Diameter of the split pin (ISO 1234) and of its hole (mm).
    washer : str
        Key of the washer under the split pin (:data:`WASHERS`).
    material : str
    """

    name: str
    diameter: float
    head_diameter: float
    head_height: float
    lengths: tuple[float, ...]
    hole_to_end: float
    split_pin: float
    washer: str
    material: str = "steel, zinc-plated"

    def clamp(self, length: float) -> float:
        """Room between the head and the split pin (mm)."""
        return length - self.hole_to_end - 0.5 * self.split_pin

    def pin(self, length: float) -> str:
        return (f"clevis pin ISO 2341 B {self.diameter:g} x {length:g} (with split-pin hole), "
                f"head {self.head_diameter:g} mm, {self.material}")

    def split(self) -> str:
        return (f"split pin ISO 1234 {self.split_pin:g} x {4 * self.diameter:g}, "
                f"{self.material}")


_PIN_LENGTHS = tuple(float(v) for v in [*range(8, 34, 2), 35, 40, 45, 50, 55, 60, 65, 70])
#: Clevis pins by shank diameter, for stacks deeper than the longest post.
PINS: dict[str, PinSpec] = {p.name: p for p in (
    PinSpec("4-pin", 4.0, 6.0, 1.0, _PIN_LENGTHS, 2.2, 1.0, "ISO 7089 M4"),
    PinSpec("5-pin", 5.0, 8.0, 1.6, _PIN_LENGTHS[1:], 2.9, 1.2, "ISO 7089 M5"),
    PinSpec("6-pin", 6.0, 10.0, 2.0, _PIN_LENGTHS[2:], 3.2, 1.6, "ISO 7089 M6"),
)}


@dataclass(frozen=True)
class ScrewSpec:
    """One catalogue entry (all lengths in mm).

    Attributes
    ----------
    name : str
    barrel_diameter : float
        Outer diameter of the barrel (the pin the bars turn on).
    hole_diameter : float
        Running hole cut in every bar (barrel + running clearance).
    head_diameter, head_height : float
        The heads at both ends of the stack.
    lengths : tuple of float
        Post lengths available, ascending.
    allowance : float
        Axial play added to the stack height before choosing a length.
    thread : str
        Thread of the screw (``"M3"``, ``"#8-32"``), as the shop names the series.
    material : str
    unit : str
        ``"mm"`` or ``"in"``: how the shop states the sizes (post lengths in inch fractions).
    extensions : tuple of float
        Lengths of the screw-on extensions sold for the series (mm; empty: none).
    pin : str or None
        Key of the clevis pin series (:data:`PINS`) for stacks deeper than the posts and their
        extensions reach.
    washer : str or None
        Key of the shim washer (:data:`WASHERS`); None: the thinnest that clears the barrel.
    family : str
        The standard or product family the entry follows, as a buyer searches for it.
    shims : tuple of str
        Keys of the shim rings (:data:`WASHERS`) that take up axial play, thickest first;
        empty: ``washer`` alone.
    """

    name: str
    barrel_diameter: float
    hole_diameter: float
    head_diameter: float
    head_height: float
    lengths: tuple[float, ...]
    allowance: float = 0.1
    thread: str = ""
    material: str = ""
    unit: str = "mm"
    extensions: tuple[float, ...] = ()
    pin: str | None = None
    washer: str | None = None
    family: str = ""
    shims: tuple[str, ...] = ()

    def as_dict(self) -> dict:
        return {f.name: (list(getattr(self, f.name)) if f.name in ("lengths", "extensions",
                                                                   "shims")
                         else getattr(self, f.name)) for f in fields(self)}

    def length_text(self, mm: float) -> str:
        """A post or extension length as the shop lists it."""
        return inch_text(mm) if self.unit == "in" else f"{mm:g} mm"

    def size_text(self, mm: float) -> str:
        return f"{inch_text(mm)} ({mm:.2f} mm)" if self.unit == "in" else f"{mm:g} mm"

    def post(self, length: float) -> str:
        """The screw of one post length as a shop lists it."""
        return (f"{self.series()}, post length {self.length_text(length)}"
                + (f", {self.material}" if self.material else ""))

    def extension(self, length: float) -> str:
        return (f"Chicago screw extension {self.thread or self.name}, "
                f"{self.length_text(length)}" + (f", {self.material}" if self.material else ""))

    def shim(self) -> Washer:
        """The (thickest) washer that takes up axial play under a head: it goes over the
        barrel."""
        return self.shim_set()[0]

    def shim_set(self) -> list:
        """The washers that take up axial play, thickest first."""
        if self.shims:
            return [WASHERS[k] for k in self.shims]
        if self.washer is not None:
            return [WASHERS[self.washer]]
        return [choose_washer(self.barrel_diameter, unit=self.unit)]

    def series(self) -> str:
        """The screw as a shop lists the series (no length): ``"Chicago screw (sex bolt) M4,
        barrel 5 mm, head 10 mm"``."""
        return (f"Chicago screw (sex bolt) {self.thread or self.name}, barrel "
                f"{self.size_text(self.barrel_diameter)}, head "
                f"{self.size_text(self.head_diameter)}")


_METRIC_LENGTHS = tuple(float(v) for v in [*range(4, 17), 18, 20, 22, 25, 28, 30])
#: Metric book screws, 5 mm barrel: the post lengths bookbinding and hardware suppliers list.
_BOOK_LENGTHS = tuple(float(v) for v in [*range(4, 11), 12, 13, 15, 18, 20, 22, 25, 30, 35, 40,
                                         45, 50])
#: Inch binding posts: lengths 1/8-2 in and their screw-on extensions (aluminium).
_INCH_LENGTHS = _inch("1/8", "3/16", "1/4", "5/16", "3/8", "7/16", "1/2", "5/8", "3/4", "7/8",
                      "1", "5/4", "3/2", "7/4", "2")
_INCH_EXTENSIONS = _inch("1/4", "1/2", "3/4", "1")


def _shim_keys(d: float) -> tuple:
    return tuple(f"DIN 988 {d:g}x{2 * d:g}x{t:g}" for t in (0.5, 0.2))


#: Built-in entries; a template may override any field of one of them.
CATALOGUE: dict[str, ScrewSpec] = {
    "M4-chicago": ScrewSpec(
        "M4-chicago", 5.0, 5.2, 10.0, 2.0, _BOOK_LENGTHS, thread="M4",
        material="stainless steel A2", pin="5-pin", shims=_shim_keys(5.0),
        family="Chicago screws (book screws, sex bolts) M4 x 5 mm barrel: the metric series "
               "bookbinding and hardware suppliers sell"),
    "M3-chicago": ScrewSpec(
        "M3-chicago", 4.0, 4.2, 8.5, 1.9, _METRIC_LENGTHS, thread="M3",
        material="stainless steel A2", pin="4-pin", shims=_shim_keys(4.0),
        family="Chicago screws (sex bolts) M3 x 4 mm barrel, a smaller metric series"),
    "M5-chicago": ScrewSpec(
        "M5-chicago", 6.0, 6.2, 12.0, 2.5, _METRIC_LENGTHS[2:], thread="M5",
        material="stainless steel A2", pin="6-pin", shims=_shim_keys(6.0),
        family="Chicago screws (sex bolts) M5 x 6 mm barrel, a larger metric series"),
    "inch-chicago": ScrewSpec(
        "inch-chicago", *_inch("3/16"), 5.0, *_inch("3/8", "1/16"), _INCH_LENGTHS,
        thread="#8-32", material="aluminium", unit="in", extensions=_INCH_EXTENSIONS,
        shims=("shim 3/16 x 3/8 x 0.020 in", "shim 3/16 x 3/8 x 0.008 in"),
        family="binding posts (Chicago screws) #8-32 UNC x 3/16 in barrel with screw-on "
               "extensions: the US series"),
}

#: The default: the metric book screw sold most widely (5 mm barrel, M4).
DEFAULT_SCREW = "M4-chicago"

_FIELDS = {f.name for f in fields(ScrewSpec)}
#: What a screw of one's own must give (the rest have defaults).
_SIZE_FIELDS = ("barrel_diameter", "hole_diameter", "head_diameter", "head_height", "lengths")


def screw_spec(entry=None) -> ScrewSpec:
    """Resolve a catalogue entry: a name, a table of overrides, or None for the default.

    Parameters
    ----------
    entry : str, dict or None
        ``"M4-chicago"``; or ``{"name": "M3-chicago", "hole_diameter": 4.3, ...}`` (fields not
        given come from the named entry, the default when no name is given).

    Returns
    -------
    ScrewSpec

    Raises
    ------
    FabricationError
        Unknown entry or field, or a non-positive / inconsistent size.

    Examples
    --------
    >>> screw_spec({"hole_diameter": 5.3}).hole_diameter
    5.3
    """
    if entry is None:
        return CATALOGUE[DEFAULT_SCREW]
    if isinstance(entry, ScrewSpec):
        spec = entry
    elif isinstance(entry, str):
        if entry not in CATALOGUE:
            raise FabricationError(f"unknown screw {entry!r}; catalogue entries: "
                                   f"{', '.join(CATALOGUE)} (or give a table with its sizes)")
        return CATALOGUE[entry]
    elif isinstance(entry, dict):
        given = check_table(ScrewSection, entry, "laser.screw").given()
        name = given.get("name")
        if name is not None and name not in CATALOGUE:
            # a screw of one's own: a misspelt catalogue name must not pass as one
            missing = [f for f in _SIZE_FIELDS if f not in given]
            if missing:
                raise FabricationError(
                    f"unknown screw {name!r}; catalogue entries: {', '.join(CATALOGUE)}; a "
                    f"screw of your own needs every size ({', '.join(missing)} missing)")
        base = CATALOGUE[name] if name in CATALOGUE else CATALOGUE[DEFAULT_SCREW]
        values = {k: (tuple(sorted(float(x) for x in v)) if k == "lengths" else
                      (v if k == "name" else float(v))) for k, v in given.items()}
        if name is not None and name not in CATALOGUE:
            # sizes of one's own: no series, extensions, pins or shims of a catalogue entry
            values.update(thread="", material="", unit="mm", extensions=(), pin=None,
                          shims=(), family="a screw of your own")
        spec = replace(base, **values)
    else:
        raise FabricationError(f"screw must be a catalogue name or a table, got {entry!r}")
    if spec.hole_diameter < spec.barrel_diameter:
        raise FabricationError(
            f"screw hole_diameter {spec.hole_diameter} mm is smaller than the barrel "
            f"{spec.barrel_diameter} mm: the bars would not turn; use barrel + 0.2 mm")
    if spec.head_diameter <= spec.hole_diameter:
        raise FabricationError(
            f"screw head_diameter {spec.head_diameter} mm must exceed the hole "
            f"{spec.hole_diameter} mm, or the head pulls through")
    return spec


def choose_length(spec: ScrewSpec, stack: float) -> float:
    """Shortest post length that clamps a stack of ``stack`` mm plus the allowance.

    Raises
    ------
    FabricationError
        When the stack is taller than the longest post in the catalogue entry.

    Examples
    --------
    >>> choose_length(screw_spec(), 6.0)
    7.0
    >>> choose_length(screw_spec(), 10.5)
    12.0
    """
    need = stack + spec.allowance
    for length in spec.lengths:
        if length >= need - MM_SLACK:
            return float(length)
    raise FabricationError(
        f"a joint stack of {stack:.2f} mm (+{spec.allowance} mm play) needs a screw longer than "
        f"the longest {spec.name} post ({spec.lengths[-1]:g} mm); add longer lengths to the screw "
        "entry, use thinner sheet, or reduce the layers (smaller bar_width or larger scale)")


def _stack(layers, thickness, tolerance):
    return (round(layers * (thickness - tolerance), 9), round(layers * thickness, 9),
            round(layers * (thickness + tolerance), 9))


def _fill(spec, room: float) -> tuple:
    """Shims (count of each kind of :meth:`ScrewSpec.shim_set`, thickest first) for ``room``
    mm less the allowance: as many of the thickest as fit, then a thinner one only while the
    play left is more than 0.4 mm, a tenth inside :data:`MAX_AXIAL_PLAY` (fewest small
    parts)."""
    kinds = spec.shim_set()
    counts = [0] * len(kinds)
    if not kinds:
        return ()
    counts[0] = max(int(math.floor(room / kinds[0].thickness + MM_SLACK)), 0)
    left = room - counts[0] * kinds[0].thickness
    for i, w in enumerate(kinds[1:], 1):
        while left + spec.allowance > _PLAY_TARGET + MM_SLACK and \
                w.thickness <= left + MM_SLACK:
            counts[i] += 1
            left -= w.thickness
    return tuple(counts)


def _take_off(spec, counts: tuple, room: float) -> tuple:
    """The shims of ``counts`` to keep where only ``room`` mm is left (the most that fit)."""
    kinds = spec.shim_set()
    best, best_fill = tuple(0 for _ in counts), 0.0
    for keep in itertools.product(*(range(n + 1) for n in counts)):
        fill = sum(k * w.thickness for k, w in zip(keep, kinds))
        if best_fill < fill <= room + MM_SLACK:
            best, best_fill = keep, fill
    return best


def _shims(spec, length, stack_min, stack_nominal, stack_max):
    """Shims for the nominal sheet, and the play on the thickest (some taken off), nominal
    and thinnest sheets."""
    kinds = spec.shim_set()
    counts = _fill(spec, length - stack_nominal - spec.allowance)
    fill = sum(n * w.thickness for n, w in zip(counts, kinds))
    thick = _take_off(spec, counts, length - stack_max - spec.allowance)
    fill_thick = sum(n * w.thickness for n, w in zip(thick, kinds))
    return (counts, round(length - stack_max - fill_thick, 9),
            round(length - stack_nominal - fill, 9), round(length - stack_min - fill, 9))


# -- the fastener of one joint ----------------------------------------------------------------

@dataclass(frozen=True)
class PartLine:
    """Parts of one kind as a shop lists them, and how many.

    Attributes
    ----------
    key : str
        Stable identifier (``"chicago:M3-chicago:12"``, ``"washer:DIN 433 M4"``).
    kind : str
        ``"chicago screw"``, ``"extension"``, ``"clevis pin"``, ``"split pin"``,
        ``"washer"``.
    description : str
        The part as a shop lists it.
    count : int
    size : dict
        The sizes that identify it in the catalogue (mm): ``post_length_mm``,
        ``barrel_diameter_mm``, ``inner_diameter_mm``, ...
    """

    key: str
    kind: str
    description: str
    count: int
    size: dict


@dataclass(frozen=True)
class Fastener:
    """What holds one joint's stack: a Chicago screw, one with extensions, or a clevis pin.

    Attributes
    ----------
    kind : str
        ``"chicago"``, ``"chicago+extensions"`` or ``"clevis pin"``.
    layers : int
    length : float
        Post length (with its extensions) or clevis pin length (mm).
    stack_min, stack_max : float
        Stack height on the thinnest and thickest sheets (mm).
    washers : int
        Shim washers taking up the axial play on the nominal sheet (all kinds).
    play_min, play_max : float
        Axial play on the thickest sheets (with the shims that still fit there) and on the
        thinnest (with the nominal sheet's shims), mm.
    extensions : tuple of float
    parts : tuple of PartLine
        What to buy for this joint.
    play_nominal : float
        Axial play with the shims on the nominal sheet (at most :data:`MAX_AXIAL_PLAY` where
        the series has its shims).
    shims : tuple of (str, float, int)
        The shims on the nominal sheet: washer key, thickness (mm), count.
    """

    kind: str
    layers: int
    length: float
    stack_min: float
    stack_max: float
    washers: int
    play_min: float
    play_max: float
    extensions: tuple = ()
    parts: tuple = ()
    unit: str = "mm"
    play_nominal: float = 0.0
    shims: tuple = ()

    @property
    def closes(self) -> bool:
        return self.play_min >= -MM_SLACK

    @property
    def post(self) -> float:
        """The post length without extensions (the pin length for a clevis pin)."""
        return self.length - sum(self.extensions)

    def describe(self) -> str:
        """One line for the guide and the BOM: ``"post 25 mm + 7 x 0.5 + 1 x 0.2 mm shims"``."""
        shims = (" + " + " + ".join(f"{n} x {t:g}" for _, t, n in self.shims if n) + " mm shims"
                 if self.washers else "")
        if self.kind == "clevis pin":
            return f"clevis pin {self.length:g} mm, washer, split pin{shims}"
        size = inch_text if self.unit == "in" else (lambda v: f"{v:g} mm")
        ext = " + ".join(size(v) for v in self.extensions)
        return f"post {size(self.post)}" + (f" + extensions {ext}" if ext else "") + shims


def _shim_lines(spec: ScrewSpec, counts, over: float) -> list:
    return [PartLine(f"washer:{w.name}", "washer", w.description(), n,
                     {"inner_diameter_mm": w.inner, "outer_diameter_mm": w.outer,
                      "thickness_mm": w.thickness, "washer": w.name, "over_mm": over})
            for w, n in zip(spec.shim_set(), counts) if n]


def _shim_record(spec: ScrewSpec, counts) -> tuple:
    return tuple((w.name, w.thickness, int(n)) for w, n in zip(spec.shim_set(), counts))


def _chicago_parts(spec: ScrewSpec, post: float, extensions, counts) -> tuple:
    lines = [PartLine(f"chicago:{spec.name}:{post:g}", "chicago screw", spec.post(post), 1,
                      {"post_length_mm": post, "barrel_diameter_mm": spec.barrel_diameter,
                       "head_diameter_mm": spec.head_diameter, "screw": spec.name})]
    for e in extensions:
        lines.append(PartLine(f"extension:{spec.name}:{e:g}", "extension", spec.extension(e), 1,
                              {"length_mm": e, "barrel_diameter_mm": spec.barrel_diameter,
                               "screw": spec.name}))
    lines += _shim_lines(spec, counts, spec.barrel_diameter)
    return tuple(lines)


def _with_extensions(spec: ScrewSpec, need: float):
    """The post and extensions (fewest parts, then shortest) reaching ``need`` mm."""
    best = None
    for k in range(1, MAX_EXTENSIONS + 1):
        for ext in itertools.combinations_with_replacement(spec.extensions, k):
            for post in spec.lengths:
                total = post + sum(ext)
                if total >= need - MM_SLACK:
                    key = (k, total)
                    if best is None or key < best[0]:
                        best = (key, post, ext)
                    break
        if best is not None:
            return best[1], tuple(sorted(best[2], reverse=True))
    return None


def _pin_set(spec: ScrewSpec, layers, stack_min, stack_nominal,
             stack_max) -> Fastener | None:
    """The shortest clevis pin whose room between head and split pin holds the stack, its
    washer and the allowance on the thickest sheets; shims take up the rest."""
    if spec.pin is None:
        return None
    p = PINS[spec.pin]
    w = WASHERS[p.washer]
    for length in p.lengths:
        room = p.clamp(length) - w.thickness
        if room >= stack_max + spec.allowance - MM_SLACK:
            counts, pmin, pnom, pmax = _shims(spec, room, stack_min, stack_nominal, stack_max)
            parts = [PartLine(f"pin:{p.name}:{length:g}", "clevis pin", p.pin(length), 1,
                              {"length_mm": length, "diameter_mm": p.diameter,
                               "pin": p.name}),
                     PartLine(f"washer:{w.name}", "washer", w.description(), 1,
                              {"inner_diameter_mm": w.inner, "outer_diameter_mm": w.outer,
                               "thickness_mm": w.thickness, "washer": w.name,
                               "over_mm": p.diameter}),
                     PartLine(f"split:{p.name}", "split pin", p.split(), 1,
                              {"diameter_mm": p.split_pin, "pin": p.name}),
                     *_shim_lines(spec, counts, p.diameter)]
            return Fastener("clevis pin", int(layers), float(length), stack_min, stack_max,
                            int(sum(counts)), pmin, pmax, parts=merge_parts(parts),
                            play_nominal=pnom, shims=_shim_record(spec, counts))
    return None


def merge_parts(lines) -> tuple:
    """Part lines of the same part (same key) added into one line, in first-seen order."""
    out: dict[str, PartLine] = {}
    for ln in lines:
        out[ln.key] = replace(ln, count=out[ln.key].count + ln.count) if ln.key in out else ln
    return tuple(out.values())


def fit_fastener(spec: ScrewSpec, layers: int, thickness: float, tolerance: float) -> Fastener:
    """The fastener of a joint of ``layers`` sheets of ``thickness +- tolerance`` mm.

    A Chicago screw of the series when a post is long enough: the shortest post that closes on
    the thickest sheets (``layers x (t + tol)`` plus the allowance); past the longest post, a
    post with screw-on extensions when the series has them; else a clevis pin of the barrel's
    diameter (:data:`PINS`) with its washer and split pin. Shims under the head take up the
    play on the nominal sheet to at most :data:`MAX_AXIAL_PLAY` (0.5 mm ones, and a thin
    one where that is not enough); on the thickest sheets the ones that no longer fit come off.

    Raises
    ------
    FabricationError
        When no fastener of the catalogue holds the stack.

    Examples
    --------
    >>> f = fit_fastener(screw_spec(), 7, 3.0, 0.15)    # 7 sheets may be 22.05 mm
    >>> f.kind, f.length, f.stack_max, f.describe()
    ('chicago', 25.0, 22.05, 'post 25 mm + 7 x 0.5 + 1 x 0.2 mm shims')
    >>> round(f.play_nominal, 2), round(f.play_min, 2), round(f.play_max, 2)
    (0.3, 0.25, 1.35)
    >>> f = fit_fastener(screw_spec(), 17, 3.0, 0.15)   # 17 sheets may be 53.55 mm
    >>> f.kind, f.length
    ('clevis pin', 60.0)
    >>> g = fit_fastener(screw_spec("inch-chicago"), 18, 3.0, 0.15)   # 56.7 mm
    >>> g.kind, inch_text(g.post), [inch_text(e) for e in g.extensions]
    ('chicago+extensions', '2 in', ['1/4 in'])
    """
    stack_min, stack_nominal, stack_max = _stack(layers, thickness, tolerance)
    need = stack_max + spec.allowance
    if need <= spec.lengths[-1] + MM_SLACK:
        length = choose_length(spec, stack_max)
        counts, pmin, pnom, pmax = _shims(spec, length, stack_min, stack_nominal, stack_max)
        return Fastener("chicago", int(layers), length, stack_min, stack_max, int(sum(counts)),
                        pmin, pmax, parts=_chicago_parts(spec, length, (), counts),
                        unit=spec.unit, play_nominal=pnom, shims=_shim_record(spec, counts))
    found = _with_extensions(spec, need) if spec.extensions else None
    if found is not None:
        post, ext = found
        length = post + sum(ext)
        counts, pmin, pnom, pmax = _shims(spec, length, stack_min, stack_nominal, stack_max)
        return Fastener("chicago+extensions", int(layers), float(length), stack_min, stack_max,
                        int(sum(counts)), pmin, pmax, extensions=ext,
                        parts=_chicago_parts(spec, post, ext, counts), unit=spec.unit,
                        play_nominal=pnom, shims=_shim_record(spec, counts))
    pin = _pin_set(spec, layers, stack_min, stack_nominal, stack_max)
    if pin is not None:
        return pin
    longest = spec.lengths[-1] + MAX_EXTENSIONS * max(spec.extensions, default=0.0)
    raise FabricationError(
        f"a joint stack of {stack_max:.2f} mm (+{spec.allowance} mm play) is deeper than any "
        f"{spec.name} fastener of the catalogue holds (posts to {longest:g} mm"
        + (f", {spec.pin} clevis pins to {PINS[spec.pin].lengths[-1]:g} mm" if spec.pin
           else "") + "); use thinner sheet, or fewer layers (smaller bar_width or larger "
        "scale)")
