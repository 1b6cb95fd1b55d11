"""3MF packages (unit millimetre), byte-for-byte reproducible, with optional slicer settings.

A 3MF is a ZIP of ``[Content_Types].xml``, ``_rels/.rels`` and ``3D/3dmodel.model`` (the core
specification, 2015/02): objects with a mesh each, and build items that place them on the
plate. Settings for PrusaSlicer (see :mod:`fabkit.fab.slicer`) travel in two more parts it reads:
``Metadata/Slic3r_PE.config`` (project: ``; key = value`` lines, which PrusaSlicer 2.5 reads
from the end of the file up to the first line that is not one, never the file's first line: a
title line comes first) and ``Metadata/Slic3r_PE_model.config`` (per object, with the object's
volumes as triangle ranges: an object listed there without volumes would be empty).

Pure: returns bytes.
"""

from __future__ import annotations

import io
import zipfile
from xml.sax.saxutils import quoteattr

import numpy as np

__all__ = ["threemf_package", "CORE_NAMESPACE", "PROJECT_CONFIG", "MODEL_CONFIG"]

CORE_NAMESPACE = "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"
#: Where PrusaSlicer reads project and per-object settings.
PROJECT_CONFIG = "Metadata/Slic3r_PE.config"
MODEL_CONFIG = "Metadata/Slic3r_PE_model.config"


def _value(v) -> str:
    if isinstance(v, bool):
        return "1" if v else "0"
    if isinstance(v, float):
        return f"{v:.9g}"
    return str(v)


def _project_text(project: dict, title: str) -> str:
    lines = [f"; {title}"] + [f"; {k} = {_value(v)}" for k, v in project.items()]
    return "\n".join(lines) + "\n"


def _model_config_text(objects, per_object: dict) -> str:
    out = ['<?xml version="1.0" encoding="UTF-8"?>', "<config>"]
    for oid, obj in enumerate(objects, start=1):
        n_tri = len(obj[1])
        volumes = obj[4] if len(obj) > 4 and obj[4] else [(0, n_tri - 1, obj[2])]
        out.append(f' <object id="{oid}" instances_count="1">')
        out.append(f'  <metadata type="object" key="name" value={quoteattr(obj[2])}/>')
        out += [f'  <metadata type="object" key="{k}" value={quoteattr(_value(v))}/>'
                for k, v in per_object.items()]
        for first, last, name in volumes:
            out.append(f'  <volume firstid="{int(first)}" lastid="{int(last)}">')
            out.append(f'   <metadata type="volume" key="name" value={quoteattr(name)}/>')
            out.append('   <metadata type="volume" key="volume_type" value="ModelPart"/>')
            out.append("  </volume>")
        out.append(" </object>")
    out.append("</config>")
    return "\n".join(out) + "\n"


def threemf_package(vertices, faces, name: str = "network", transform=None, *,
                    objects=None, project: dict | None = None,
                    per_object: dict | None = None,
                    title: str = "fabkit print settings") -> bytes:
    """A 3MF package (unit millimetre), byte-for-byte reproducible.

    Parameters
    ----------
    vertices : array_like, shape (V, 3)
    faces : array_like of int, shape (F, 3)
    name : str
    transform : array_like, shape (3, 4), optional
        Placement of the object on the build plate (``x' = R x + t``, mm).
    objects : list of tuples, optional
        Several objects instead of the one above: ``(vertices, faces, name, transform)`` or
        ``(vertices, faces, name, transform, volumes)`` with ``volumes`` a list of
        ``(first_triangle, last_triangle, name)`` (inclusive ranges) naming its parts.
    project : dict, optional
        Project settings for PrusaSlicer (``Metadata/Slic3r_PE.config``).
    per_object : dict, optional
        Settings of every object for PrusaSlicer (``Metadata/Slic3r_PE_model.config``).
    title : str
        First line of the project settings.

    Returns
    -------
    bytes
        A ZIP archive.

    Examples
    --------
    >>> data = threemf_package([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
    ...                        [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    ...                        per_object={"layer_height": 0.2})
    >>> sorted(zipfile.ZipFile(io.BytesIO(data)).namelist())[:2]
    ['3D/3dmodel.model', 'Metadata/Slic3r_PE_model.config']
    """
    if objects is None:
        objects = [(vertices, faces, name, transform)]
    resources, items = [], []
    for oid, obj in enumerate(objects, start=1):
        vv, ff, nm, tr = obj[:4]
        v = np.asarray(vv, dtype=np.float32)
        f = np.asarray(ff, dtype=np.int64)
        # nine significant digits give back every float32 exactly (half the time of Python's
        # shortest repr of the float64 it widens to, a third less text)
        vtxt = "".join(f'<vertex x="{a:.9g}" y="{b:.9g}" z="{c:.9g}"/>'
                       for a, b, c in v.astype(float).tolist())
        ftxt = "".join(f'<triangle v1="{a}" v2="{b}" v3="{c}"/>' for a, b, c in f.tolist())
        resources.append(f'<object id="{oid}" type="model" name={quoteattr(nm)}>'
                         f'<mesh><vertices>{vtxt}</vertices><triangles>{ftxt}</triangles></mesh>'
                         '</object>')
        if tr is None:
            items.append(f'<item objectid="{oid}"/>')
        else:
            m = np.asarray(tr, dtype=np.float64)
            # 3MF matrices act on row vectors: m00 m01 m02 m10 m11 m12 m20 m21 m22 m30 m31 m32
            vals = list(m[:3, :3].T.ravel()) + list(m[:3, 3])
            items.append(f'<item objectid="{oid}" transform="'
                         + " ".join(f"{x:.9g}" for x in vals) + '"/>')
    model = (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        f'<model unit="millimeter" xml:lang="en-US" xmlns="{CORE_NAMESPACE}">'
        '<resources>' + "".join(resources) + '</resources><build>' + "".join(items)
        + '</build></model>')
    extra = []
    if project:
        extra.append((PROJECT_CONFIG, _project_text(project, title)))
    if per_object:
        extra.append((MODEL_CONFIG, _model_config_text(objects, per_object)))
    config_type = ('<Default Extension="config" ContentType="text/plain"/>' if extra else "")
    types = ('<?xml version="1.0" encoding="UTF-8"?>\n'
             '<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">'
             '<Default Extension="rels" '
             'ContentType="application/vnd.openxmlformats-package.relationships+xml"/>'
             '<Default Extension="model" '
             'ContentType="application/vnd.ms-package.3dmanufacturing-3dmodel+xml"/>'
             + config_type + '</Types>')
    rels = ('<?xml version="1.0" encoding="UTF-8"?>\n'
            '<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">'
            '<Relationship Target="/3D/3dmodel.model" Id="rel0" '
            'Type="http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"/>'
            '</Relationships>')
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for arcname, text in (("[Content_Types].xml", types), ("_rels/.rels", rels),
                              ("3D/3dmodel.model", model), *extra):
            info = zipfile.ZipInfo(arcname, date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            z.writestr(info, text.encode("utf-8"))
    return buf.getvalue()
