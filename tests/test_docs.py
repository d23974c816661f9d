"""The documentation runs as written: the README (the front page) and the site's pages
under ``docs/``, their code, their walkthroughs and the figures they draw; the site builds in
strict mode; the reference is a page per face, and the public names have their docstrings."""

import re

import pytest

import docs_pages
from docs_pages import DOCS, README, ROOT


@pytest.mark.slow
@pytest.mark.parametrize("path", list(docs_pages.pages()), ids=docs_pages.name)
def test_every_python_block_on_every_page_runs(path, monkeypatch, capsys):
    """A page's Python blocks run in order from the clone's root, one namespace for the page
    (a later block uses an earlier one's names); where a text block follows, each of its
    lines is in what the block printed."""
    from data import data_folder

    monkeypatch.chdir(ROOT)  # the pages' paths are the clone's (../shared/data/...)
    names: dict = {}
    for block, shown in _blocks(path.read_text(), "python"):
        for folder in re.findall(r"shared/data/([\w-]+)", block):
            data_folder(folder)  # a block on the recordings: fail in CI, skip without them
        exec(compile(block, str(path), "exec"), names)
        _printed_as_shown(path, capsys.readouterr().out, shown)


def test_readme_starts_with_the_two_setup_commands():
    text = README.read_text()
    commands = re.findall(r"```sh\n(.*?)```", text, flags=re.S)[0].strip().splitlines()
    assert [line.split("#")[0].strip() for line in commands] == ["make demo", "make test"]


def test_the_readme_is_a_front_page_that_links_into_the_site():
    """At most 250 lines; every relative link lands on a file of the site or the clone."""
    text = README.read_text()
    assert len(text.splitlines()) <= 250
    assert "a C compiler" in text.split("```sh", 1)[0]
    links = re.findall(r"\]\(([^)#:]+)(?:#[^)]*)?\)", re.sub(r"```.*?```", "", text, flags=re.S))
    assert links, "the README links none of the site's pages"
    assert sorted(link for link in links if not (ROOT / link).is_file()) == []


def test_the_readme_and_the_site_home_give_the_same_tour():
    """The README is the repository's front page and ``docs/index.md`` the site's; their
    set-up and tour are one text, held equal here."""
    readme, home = README.read_text(), (DOCS / "index.md").read_text()

    def tour(text: str) -> str:
        start = text.index("On a fresh machine with Python 3.10+")
        shown = text.index("```text")
        return text[start : text.index("```", shown + 3)]

    assert tour(readme) == tour(home)


def test_the_pages_speak_to_users():
    for path, text in docs_pages.pages().items():
        for internal in ("seed 000's main job", "Issue ", "issue "):
            assert internal not in text, (path, internal)


# Commands the shell blocks hold that the tests do not run, and why.
EXEMPT = {
    "make demo": "the README's set-up: CI and the fresh-clone check run it",
    "make test": "the README's set-up: CI and the fresh-clone check run it",
    ".venv/bin/pip install": "an install step: the tests' environment has every extra",
    ".venv/bin/diffdrive learn": "serves the page until stopped: test_learn_browser.py uses it",
}


def _inputs(name: str, where):
    """A file a page's block reads that none of its blocks writes, made as the page says."""
    import shutil

    from data import data_folder
    from sysid_log import write_sysid

    robots = {"husky.toml": "wheel_radius = 0.165\ntrack_width = 0.555\n",
              "nominal.toml": "wheel_radius = 0.042\ntrack_width = 0.2\n"}  # fmt: skip
    if name in robots:
        (where / name).write_text(robots[name])
    elif name in ("run1.csv", "run2.csv"):
        runs = sorted((data_folder("optiodom-diffdrive") / "free" / "030120210006").glob("*run*"))
        shutil.copy(runs[int(name[3]) - 1], where / name)
    elif name == "sysid.csv":
        write_sysid(where / name, 0.042)


def _blocks(text: str, language: str = "sh") -> list[tuple[str, str | None]]:
    """Each block of ``language`` and the text block right after it, if any (what it
    prints)."""
    pattern = rf"```{language}\n(.*?)```\s*?(?:\n\s*```text\n(.*?)```)?"
    return [(match.group(1), match.group(2)) for match in re.finditer(pattern, text, re.S)]


def _printed_as_shown(path, printed: str, shown: str | None) -> None:
    """Each line a page shows after a block is in what the block printed (whitespace runs as
    one space)."""
    if shown:
        flat = " ".join(printed.split())
        for expected in filter(None, (" ".join(line.split()) for line in shown.splitlines())):
            assert expected in flat, (path, expected)


@pytest.mark.slow
@pytest.mark.parametrize("path", list(docs_pages.pages()), ids=docs_pages.name)
def test_every_shell_block_on_every_page_runs_and_prints_what_it_shows(
    path, tmp_path, monkeypatch, capsys
):
    """Each page's shell blocks in order, as one shell session in a new folder: ``NAME=value``
    sets a variable, ``../shared/data/`` is the recordings (a test on them fails in CI and
    skips elsewhere without them), each ``.venv/bin/diffdrive`` command must exit 0, a file a
    block reads that no block wrote is made as the page describes it (``_inputs``), the
    clone's folders a path names exist, where a text block follows each of its lines is in
    what the block printed, and a figure drawn into ``docs/figures/`` is the site's."""
    import glob
    import shlex

    from data import data_folder
    from diffdrive.cli import main

    monkeypatch.chdir(tmp_path)
    variables: dict[str, str] = {}
    for block, shown in _blocks(path.read_text()):
        printed = ""
        for line in block.replace("\\\n", " ").splitlines():
            command = line.split(" #")[0].strip()
            if not command or any(command.startswith(start) for start in EXEMPT):
                continue
            for folder in re.findall(r"\.\./shared/data/([\w-]+)", command):
                command = command.replace(f"../shared/data/{folder}", str(data_folder(folder)))
            assignment = re.fullmatch(r"(\w+)=(.*)", command)
            if assignment:
                variables[assignment.group(1)] = shlex.split(assignment.group(2))[0]
                continue
            for name, value in sorted(variables.items(), key=lambda item: -len(item[0])):
                command = command.replace(f"${name}", value)
            words = [
                match
                for word in shlex.split(command)
                for match in (sorted(glob.glob(word)) if "*" in word else [word])
            ]  # the shell's globbing, as a page's reader's shell does it
            assert words[0] == ".venv/bin/diffdrive", (path, command)
            for word in words[1:]:
                if re.fullmatch(r"[\w-]+\.(csv|toml)", word) and not (tmp_path / word).exists():
                    _inputs(word, tmp_path)
                if "/" in word and not word.startswith("/"):  # docs/figures/... as in the clone
                    (tmp_path / word).parent.mkdir(parents=True, exist_ok=True)
            code = main(words[1:])
            out, err = capsys.readouterr()
            assert code == 0, (path, command, err)
            printed += out
        _printed_as_shown(path, printed, shown)
    _same_figures(tmp_path)


def _same_figures(folder) -> None:
    """A figure the blocks drew into ``docs/figures/`` is the one the site shows."""
    import matplotlib.image

    for made in sorted((folder / "docs" / "figures").glob("*.png")):
        shown = matplotlib.image.imread(DOCS / "figures" / made.name)
        drawn = matplotlib.image.imread(made)
        assert drawn.shape == shown.shape, made.name
        assert abs(float(drawn.mean()) - float(shown.mean())) < 1e-3, made.name


def _public_modules() -> list[str]:
    """Every public module: no part of its name begins with an underscore; the command
    line's and the compiled back ends' internals are not the library's API."""
    source = ROOT / "src" / "diffdrive"
    names = []
    for path in sorted(source.rglob("*.py")):
        parts = list(path.relative_to(source.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        if any(part.startswith("_") for part in parts) or parts[-1] == "__main__":
            continue
        if len(parts) > 1 and parts[1] in ("cli", "backends"):
            continue
        names.append(".".join(parts))
    return names


# The faces a user imports: each has one reference page, which documents its __all__.
FACES = (
    "diffdrive", "diffdrive.se2", "diffdrive.integrate", "diffdrive.model", "diffdrive.encoders",
    "diffdrive.errors", "diffdrive.atomic", "diffdrive.sensor_noise", "diffdrive.evaluation",
    "diffdrive.montecarlo", "diffdrive.distributed", "diffdrive.plot", "diffdrive.demo",
    "diffdrive.batch", "diffdrive.calibration", "diffdrive.calibration.noise",
    "diffdrive.control", "diffdrive.dynamics", "diffdrive.estimation", "diffdrive.export",
    "diffdrive.io", "diffdrive.io.ros", "diffdrive.learn", "diffdrive.learn.lessons",
    "diffdrive.sensors", "diffdrive.cli",
)  # fmt: skip


def _reference_page(module: str) -> str:
    parts = module.split(".")[1:]
    package = ROOT / "src" / "diffdrive" / "/".join(parts) / "__init__.py"
    return "/".join(["reference", *parts, "index.md"] if package.is_file() or not parts else
                    ["reference", *parts[:-1], parts[-1] + ".md"])  # fmt: skip


def test_the_reference_is_one_page_per_face_and_every_module_is_behind_one():
    """The reference documents the faces a user imports, a page each (at most 40), not the
    layout: every public module lies inside a face (its package, or the top level)."""
    nav = (ROOT / "mkdocs.yml").read_text()
    pages = sorted(str(p.relative_to(DOCS)) for p in (DOCS / "reference").rglob("*.md"))
    assert len(pages) <= 40
    assert pages == sorted(_reference_page(face) for face in FACES)
    for face in FACES:
        page = _reference_page(face)
        assert f"::: {face}\n" in (DOCS / page).read_text(), page
        assert f"- {face}: {page}" in nav, page
    packages = {face for face in FACES if (ROOT / "src" / face.replace(".", "/")).is_dir()}
    for module in _public_modules():
        assert module.rsplit(".", 1)[0] in packages or module in FACES, module


def _documented(owner: object, name: str, value: object) -> bool:
    doc = getattr(value, "__doc__", None)
    if isinstance(value, property | staticmethod | classmethod):
        doc = getattr(value, "__func__", getattr(value, "fget", None)).__doc__
    # A dataclass without a docstring gets its signature as one.
    generated = isinstance(value, type) and bool(doc) and doc.startswith(f"{name}(")
    return bool(doc and doc.strip()) and not generated


def test_every_name_a_face_exports_is_documented():
    """Every name in a face's ``__all__`` (what a user imports: classes, functions, constants
    and type aliases) has a docstring where the reference reads it, griffe's static view of
    the source, which mkdocstrings renders: a constant's is the string after it. A submodule
    a face exports is a face itself. At least 95 %; what lacks one is listed."""
    import importlib

    griffe = pytest.importorskip("griffe")
    package = griffe.load(
        "diffdrive", search_paths=[str(ROOT / "src")], resolve_aliases=True,
        resolve_external=False,
    )  # fmt: skip
    names, lacking = 0, []
    for face in FACES:
        view = package if face == "diffdrive" else package[face.split(".", 1)[1]]
        exported = getattr(importlib.import_module(face), "__all__", None)
        if exported is None:  # a module without __all__: what it defines under a public name
            exported = [
                name for name, member in view.members.items()
                if not name.startswith("_") and not member.is_alias
            ]  # fmt: skip
        for name in exported:
            member = view[name]
            target = member.final_target if member.is_alias else member
            names += 1
            if target.kind.value == "module":
                if f"{face}.{name}" not in FACES:
                    lacking.append(f"{face}.{name} (a module that is no face)")
            elif not (target.docstring and target.docstring.value.strip()):
                lacking.append(f"{face}.{name}")
    share = 1 - len(lacking) / names
    print(f"reference: {names - len(lacking)} of the faces' {names} names documented ({share:.1%})")
    assert share >= 0.95, "\n".join(lacking)
    assert lacking == [], "\n".join(lacking)  # today every one: keep it so


def test_the_public_api_is_documented():
    """At least 95 % of the public names (each module's ``__all__``, or its own public
    functions and classes, and their public methods and properties) have a docstring; what
    lacks one is listed."""
    import importlib
    import inspect

    names, lacking = 0, []
    for module_name in _public_modules():
        module = importlib.import_module(module_name)
        exported = getattr(module, "__all__", None)
        if exported is None:
            exported = [
                name for name, value in vars(module).items()
                if not name.startswith("_") and (inspect.isfunction(value) or
                inspect.isclass(value)) and value.__module__ == module_name
            ]  # fmt: skip
        for name in exported:
            value = getattr(module, name)
            if inspect.ismodule(value) or not (inspect.isfunction(value) or
                                               inspect.isclass(value)):  # fmt: skip
                continue  # constants are documented where they are set
            if getattr(value, "__module__", module_name) != module_name:
                continue  # a re-export: counted in its own module
            names += 1
            if not _documented(module, name, value):
                lacking.append(f"{module_name}.{name}")
            if inspect.isclass(value):
                for member, attribute in vars(value).items():
                    if member.startswith("_") or not (
                        inspect.isfunction(attribute)
                        or isinstance(attribute, property | staticmethod | classmethod)
                    ):
                        continue
                    names += 1
                    if not _documented(value, member, attribute):
                        lacking.append(f"{module_name}.{name}.{member}")
    share = 1 - len(lacking) / names
    print(f"docstrings: {names - len(lacking)} of {names} public names ({share:.1%})")
    assert share >= 0.95, "\n".join(lacking)
