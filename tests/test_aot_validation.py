"""The ahead-of-time extension and its manifest are checked before use; a bad one bypassed.

No build here: a manifest and an extension file are laid out in a temporary
package directory, matching this tree and CPU, and then damaged. A damaged
one is never loaded (a truncated extension whose ELF header is intact would
kill the process with SIGBUS): one line says so and numba is used instead.
"""

import json

import pytest

from allsky import aot


@pytest.fixture()
def package(tmp_path, monkeypatch):
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    monkeypatch.setattr(aot, "PACKAGE_DIR", str(pkg))
    monkeypatch.setattr(aot, "MANIFEST", str(pkg / "_aot.json"))
    monkeypatch.setattr(aot, "stamp", lambda: "s")
    monkeypatch.setattr(aot, "cpu_fingerprint", lambda: "c")
    aot.read_manifest.cache_clear()
    aot._module_if_valid.cache_clear()
    yield pkg
    aot.read_manifest.cache_clear()
    aot._module_if_valid.cache_clear()


def _manifest(pkg, **extra):
    import sys

    m = {"stamp": "s", "cpu": "c", "cache_tag": sys.implementation.cache_tag,
         "exports": {}, **extra}
    (pkg / "_aot.json").write_text(json.dumps(m))


def _one_note(capsys, words):
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("allsky: note: ") and words in lines[0], err


def test_a_truncated_extension_is_bypassed_unloaded(package, capsys):
    ext = package / "_aot.cpython-311-x86_64-linux-gnu.so"
    ext.write_bytes(b"\x7fELF" + bytes(4000))
    _manifest(package, extension={"file": ext.name, **aot.file_digest(ext)})
    ext.write_bytes(ext.read_bytes()[:1000])  # truncated, the ELF header intact
    assert aot._module_if_valid() is None
    _one_note(capsys, "the ahead-of-time extension is damaged")


BAD_MANIFESTS = ['{"stamp": 1}', "[1, 2]", '{"stamp": "s", "cache_tag": "x", "exports": [1]}',
                 "{not json",
                 '{"stamp": "s", "cache_tag": "x", "exports": {}, "extension": {"file": "../x"}}']


@pytest.mark.parametrize("text", BAD_MANIFESTS)
def test_a_manifest_of_the_wrong_shape_is_bypassed(package, capsys, text):
    (package / "_aot.json").write_text(text)
    assert aot.read_manifest() is None and aot._module_if_valid() is None
    _one_note(capsys, "manifest")


def test_an_extension_without_a_recorded_digest_is_loaded_in_a_child_first(package,
                                                                           monkeypatch,
                                                                           capsys):
    # A module whose loading kills its process, as a truncated extension does (SIGBUS).
    (package.parent / "allsky_fake_aot.py").write_text(
        "import os, signal\nos.kill(os.getpid(), signal.SIGBUS)\n")
    monkeypatch.setattr(aot, "MODULE", "allsky_fake_aot")
    _manifest(package)
    assert aot._module_if_valid() is None  # this process lives
    _one_note(capsys, "killed by signal 7")
