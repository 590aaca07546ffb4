"""The guard in front of Mitsuba's parser: hostile files refused with file:line, nothing resolved outside the
scene's folder, sizes bounded, notes and the content digest."""
import os

import pytest

from ssbench.scenes import SceneError, mitsuba_guard
from ssbench.scenes.mitsuba_guard import check_defines, guard

OK = '<scene version="3.0.0">\n  <shape type="sphere"/>\n</scene>\n'


def write(folder, text, name="scene.xml"):
    p = folder / name
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(text)
    return p


def refused(path, defines=()) -> str:
    with pytest.raises(SceneError) as e:
        guard(path, defines)
    return str(e.value)


def test_entities_and_doctype_are_refused_before_anything_expands(tmp_path):
    secret = tmp_path / "secret.txt"
    secret.write_text("TOP-SECRET")
    xxe = (f'<?xml version="1.0"?>\n<!DOCTYPE scene [\n  <!ENTITY xxe SYSTEM "file://{secret}">\n]>\n'
           '<scene version="3.0.0"><shape type="&xxe;"/></scene>\n')
    msg = refused(write(tmp_path, xxe))
    assert msg.startswith(f"{tmp_path / 'scene.xml'}:2:") and "DOCTYPE" in msg and "TOP-SECRET" not in msg
    laughs = ('<?xml version="1.0"?>\n<!DOCTYPE lolz [<!ENTITY lol "lol"><!ENTITY lol2 "&lol;&lol;&lol;">]>\n'
              '<scene version="3.0.0">&lol2;</scene>\n')
    assert "DOCTYPE" in refused(write(tmp_path, laughs))
    assert "malformed XML" in refused(write(tmp_path, '<scene version="3.0.0"><a>&undefined;</a></scene>'))
    assert refused(write(tmp_path, "")).startswith(f"{tmp_path / 'scene.xml'}:1: malformed XML")
    assert "root element must be <scene>" in refused(write(tmp_path, "<world/>"))


@pytest.mark.parametrize("name", ["../outside.xml", "sub/../../outside.xml", "/etc/passwd"])
def test_includes_outside_the_folder_are_refused(tmp_path, name):
    (tmp_path / "outside.xml").write_text(OK)
    folder = tmp_path / "scene"
    p = write(folder, f'<scene version="3.0.0">\n\n  <include filename="{name}"/>\n</scene>')
    msg = refused(p)
    assert msg.startswith(f"{p.resolve()}:3:") and ("outside the scene's folder" in msg or "absolute" in msg), msg


def test_file_names_are_checked_inside_includes_and_after_substitution(tmp_path):
    (tmp_path / "mesh.ply").write_text("ply\n")
    folder = tmp_path / "scene"
    write(folder, '<scene version="3.0.0">\n<shape type="ply">\n<string name="filename" value="$mesh"/>\n'
                  '</shape></scene>', "parts/objects.xml")
    p = write(folder, '<scene version="3.0.0"><default name="mesh" value="ok.ply"/>'
                      '<include filename="parts/objects.xml"/></scene>')
    (folder / "ok.ply").write_text("ply\n")
    guard(p)                                                        # the default names a file inside
    msg = refused(p, {"mesh": "../mesh.ply"})                       # -D pointing outside
    assert msg.startswith(f"{(folder / 'parts' / 'objects.xml').resolve()}:3:") and "outside" in msg
    assert "not found" in refused(p, {"mesh": "missing.ply"})


def test_a_symbolic_link_out_of_the_folder_is_refused(tmp_path):
    (tmp_path / "secret.ply").write_text("ply\n")
    folder = tmp_path / "scene"
    folder.mkdir()
    try:
        os.symlink(tmp_path / "secret.ply", folder / "link.ply")
    except OSError:
        pytest.skip("no symbolic links here")
    p = write(folder, '<scene version="3.0.0"><shape type="ply"><string name="filename" value="link.ply"/>'
                      '</shape></scene>')
    assert "outside the scene's folder" in refused(p)


def test_sizes_and_counts_are_bounded(tmp_path, monkeypatch):
    p = write(tmp_path, '<scene version="3.0.0">\n<sensor type="perspective"><film type="hdrfilm">\n'
                        '<integer name="width" value="$w"/></film></sensor></scene>')
    msg = refused(p, {"w": "100000"})
    assert msg.startswith(f"{p.resolve()}:3:") and "width 100000" in msg
    guard(p, {"w": "640"})
    monkeypatch.setattr(mitsuba_guard, "MAX_ELEMENTS", 50)
    many = '<scene version="3.0.0">' + '<shape type="sphere"/>' * 60 + "</scene>"
    assert "more than 50 elements" in refused(write(tmp_path, many))
    monkeypatch.setattr(mitsuba_guard, "MAX_XML_BYTES", 100)
    assert "above 100 bytes" in refused(write(tmp_path, OK + " " * 200))


def test_recursive_includes_stop_at_the_depth_limit(tmp_path):
    p = write(tmp_path, '<scene version="3.0.0"><include filename="scene.xml"/></scene>')
    assert "nested more than" in refused(p)


def test_defines_are_names_and_plain_values():
    assert check_defines({"b": 2, "a": "x"}) == (("a", "x"), ("b", "2"))
    for bad in ({"1x": "v"}, {"a-b": "v"}, {"a": "x<y"}, {"a": "two\nlines"}, [("a",)]):
        with pytest.raises(ValueError, match="defines"):
            check_defines(bad)


def test_notes_max_depth_and_digest(tmp_path):
    text = ('<scene version="3.0.0"><default name="d" value="3"/>\n'
            '<integrator type="path"><integer name="max_depth" value="$d"/></integrator>\n'
            '<sensor type="thinlens"><float name="aperture_radius" value="0.1"/>'
            '<float name="focus_distance" value="2"/><sampler type="independent"/>'
            '<film type="hdrfilm"><rfilter type="gaussian"/></film></sensor><shape type="sphere"/></scene>')
    p = write(tmp_path, text)
    g = guard(p)
    assert g.max_depth == 3 and guard(p, {"d": "-1"}).max_depth == mitsuba_guard.UNLIMITED_DEPTH
    for word in ("integrator", "aperture_radius", "focus_distance", "sampler", "rfilter"):
        assert any(word in n for n in g.notes), (word, g.notes)
    assert all(n.startswith(f"{p.resolve()}:") for n in g.notes)
    assert guard(p).digest == g.digest and guard(p, {"d": "4"}).digest != g.digest
    p.write_text(text.replace('value="3"', 'value="5"'))
    assert guard(p).digest != g.digest
    assert guard(write(tmp_path, OK, "bare.xml")).max_depth == mitsuba_guard.UNLIMITED_DEPTH
