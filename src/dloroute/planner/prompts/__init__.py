"""The VLM planner's prompts: markdown data files in this folder, assembled per variant.

The system prompt of a variant is the concatenation of its parts (``VARIANT_PARTS``); the variant
without failure reasoning drops the Flatten definition and the failure text (the paper's ablation).
Per-call messages come from the templates ``plan.md``, ``status.md`` and ``failure_status.md``, whose
``{name}`` placeholders are filled by :func:`render_template` (no template engine). The in-context
examples are listed in ``examples/manifest.json`` (skill label, clip, image file, caption).
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Literal

from dloroute.types import SkillName

Variant = Literal["failure_reasoning", "no_failure_reasoning"]

VARIANT_PARTS: dict[Variant, tuple[str, ...]] = {
    "failure_reasoning": (
        "system",
        "task",
        "scene",
        "skills",
        "skill_flatten",
        "reasoning",
        "criteria",
        "failure_reasoning",
    ),
    "no_failure_reasoning": ("system", "task", "scene", "skills", "reasoning", "criteria"),
}
VARIANT_SKILLS: dict[Variant, tuple[SkillName, ...]] = {
    "failure_reasoning": ("insert", "pull", "flatten"),
    "no_failure_reasoning": ("insert", "pull"),
}

_PLACEHOLDER = re.compile(r"\{([a-z_]+)\}")


@dataclass(frozen=True)
class PromptExample:
    """One in-context example: the correct ``skill`` on ``clip`` for the situation in ``image_png``."""

    skill: SkillName
    clip: str
    caption: str
    image_name: str
    image_png: bytes


@dataclass(frozen=True)
class PromptBundle:
    """Everything the VLM planner sends besides the step's images: texts, templates and examples."""

    variant: Variant
    system: str
    skills: tuple[SkillName, ...]
    plan_template: str
    status_template: str
    failure_status_template: str
    examples_intro: str
    examples: tuple[PromptExample, ...]

    @property
    def failure_reasoning(self) -> bool:
        return self.variant == "failure_reasoning"


def prompts_dir() -> Path:
    """The folder holding the prompt files (inside the installed package)."""
    return Path(str(resources.files(__name__)))


def render_template(template: str, **values: object) -> str:
    """Fill ``{name}`` placeholders; raises KeyError naming any placeholder without a value.

    Only lower-case identifiers in braces are placeholders, so JSON snippets in a template stay intact.
    """
    missing = sorted({m for m in _PLACEHOLDER.findall(template) if m not in values})
    if missing:
        raise KeyError(f"template placeholders without a value: {', '.join(missing)}")
    return _PLACEHOLDER.sub(lambda m: str(values[m.group(1)]), template)


def load_prompt(variant: Variant = "failure_reasoning", *, examples_dir: Path | None = None) -> PromptBundle:
    """The prompt of ``variant``; example images are read from ``examples_dir`` (default: the package's).

    Raises FileNotFoundError naming the missing example image and how to render it.
    """
    if variant not in VARIANT_PARTS:
        raise ValueError(f"unknown prompt variant {variant!r}; choose one of {', '.join(VARIANT_PARTS)}")
    root = prompts_dir()
    text = {p.stem: p.read_text(encoding="utf-8").strip() for p in root.glob("*.md")}
    images = examples_dir or root / "examples"
    manifest = json.loads((root / "examples" / "manifest.json").read_text(encoding="utf-8"))
    examples = []
    for ex in manifest["examples"]:
        path = images / ex["image"]
        if not path.is_file():
            raise FileNotFoundError(
                f"in-context example image {path} is missing; render it with "
                "`python -c 'from dloroute.planner.prompts_examples import render_examples; render_examples()'`"
            )
        examples.append(PromptExample(ex["skill"], ex["clip"], ex["caption"], ex["image"], path.read_bytes()))
    return PromptBundle(
        variant=variant,
        system="\n\n".join(text[part] for part in VARIANT_PARTS[variant]),
        skills=VARIANT_SKILLS[variant],
        plan_template=text["plan"],
        status_template=text["status"],
        failure_status_template=" " + text["failure_status"],
        examples_intro=text["examples"],
        examples=tuple(examples),
    )
