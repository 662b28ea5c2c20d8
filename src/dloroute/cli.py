"""``dloroute`` command line: thin wrappers over the library."""

from __future__ import annotations

from pathlib import Path

import typer

app = typer.Typer(add_completion=False, no_args_is_help=True, help=__doc__)


@app.callback()
def _root() -> None:
    """Route a rope through clips in simulation; train and evaluate the skills and planners."""


@app.command("train-insert")
def train_insert(
    steps: int = typer.Option(6200, help="Environment steps (Insert primitives); the paper uses 6.2k."),
    seed: int = typer.Option(0, help="Seed of the environments and the learner."),
    n_envs: int = typer.Option(2, help="Parallel environment processes (one per core)."),
    bend_probability: float = typer.Option(0.5, help="Share of episodes starting from a curved rope (0 = paper)."),
    curriculum_steps: int = typer.Option(1600, help="Steps at clip scale U(1.0, 2.2) before U(0.9, 1.5)."),
    learning_starts: int = typer.Option(300, help="Random-action steps before learning."),
    demo_steps: int = typer.Option(0, help="Scripted-insertion steps put in the replay buffer first (0 = paper's SAC)."),
    gradient_steps: int = typer.Option(2, help="Gradient steps per vectorised environment step."),
    gamma: float = typer.Option(0.9, help="Discount factor."),
    out: Path = typer.Option(Path("runs/train_insert"), help="Run folder (TensorBoard logs, weights, card)."),
    resume: Path | None = typer.Option(None, help="Continue an earlier run folder (checkpoint + replay buffer)."),
    install: bool = typer.Option(False, help="Copy the exported actor and card into the package as the shipped policy."),
) -> None:
    """Train the Insert policy with SAC (Stable-Baselines3) and export the actor's weights."""
    import shutil

    from dloroute.skills.policy import SHIPPED
    from dloroute.skills.train_sac import TrainConfig, train

    config = TrainConfig(
        steps=steps, seed=seed, n_envs=n_envs, bend_probability=bend_probability, curriculum_steps=curriculum_steps, learning_starts=learning_starts, demo_steps=demo_steps,
        gradient_steps=gradient_steps, gamma=gamma, out=str(out), resume=str(resume) if resume else None,
    )
    path = train(config)
    typer.echo(f"actor weights: {path} (card: {path.with_suffix('.json')})")
    if install:
        dest = Path(__file__).parent / "skills" / "policies"
        shutil.copy(path, dest / SHIPPED)
        shutil.copy(path.with_suffix(".json"), (dest / SHIPPED).with_suffix(".json"))
        typer.echo(f"installed as the shipped policy in {dest}")


FAMILY_HELP = "Task family: implicit, fixed_spatial, fixed_attribute or clips_4_5 (dashes also accepted)."


def _family(name: str) -> str:
    return name.replace("-", "_")


def _vlm_config(model: str | None, base_url: str | None, api_key_env: str, reasoning_effort: str | None):
    from dloroute.planner.vlm import VLMConfig

    fields = {"api_key_env": api_key_env}
    if model:
        fields["model"] = model
    if base_url:
        fields["base_url"] = base_url
    if reasoning_effort:
        fields["reasoning_effort"] = reasoning_effort
    return VLMConfig(**fields)


@app.command()
def route(
    family: str = typer.Option("fixed_attribute", help=FAMILY_HELP),
    seed: int = typer.Option(3, help="Scene seed: the same seed gives the same layout and episode."),
    instruction: str | None = typer.Option(None, help="Replace the generated instruction (same layout)."),
    planner: str = typer.Option("rule_based", help="vlm, vlm_no_fr, fixed_order, symbolic or rule_based."),
    low_level: str = typer.Option("rl", help="Insert skill: rl (the shipped SAC policy) or heuristic."),
    perception: str = typer.Option("oracle", help="oracle (simulator state) or image (segmentation)."),
    policy: Path | None = typer.Option(None, help="Insertion policy weights (.npz); default: the shipped one."),
    vlm_model: str | None = typer.Option(None, help="VLM model name (e.g. gpt-5, Qwen/Qwen2.5-VL-7B-Instruct)."),
    vlm_base_url: str | None = typer.Option(None, help="OpenAI-compatible base URL (vLLM, Ollama, ...)."),
    vlm_api_key_env: str = typer.Option("OPENAI_API_KEY", help="Name of the environment variable with the key."),
    vlm_reasoning_effort: str | None = typer.Option(None, help="Reasoning effort for reasoning models (low, ...)."),
    vlm_replay: Path | None = typer.Option(None, help="Replay the VLM's answers from a recorded vlm_calls folder (offline)."),
    out: Path = typer.Option(Path("runs/route"), help="Folder for episode.mp4, result.json, scene.json."),
    video: bool = typer.Option(True, help="Write the episode video."),
    step_limit: int | None = typer.Option(None, help="Pick-and-place primitives allowed; default 8 x clips + 6."),
) -> None:
    """Run one routing episode: print each step, write a video and a JSON result."""
    import dataclasses

    from rich.console import Console

    from dloroute.routing.episode import EpisodeConfig, run_episode, write_result
    from dloroute.sim.scene import generate_scene

    console = Console()
    scene = generate_scene(_family(family), seed)
    if instruction:
        scene = dataclasses.replace(scene, instruction=instruction)
    out.mkdir(parents=True, exist_ok=True)
    (out / "scene.json").write_text(scene.to_json() + "\n")
    console.print(f"[bold]{scene.family}[/] seed {seed}: {scene.instruction}  (clips: {', '.join(c.name for c in scene.clips)})")
    vlm = _vlm_config(vlm_model, vlm_base_url, vlm_api_key_env, vlm_reasoning_effort) if planner.startswith("vlm") else None
    config = EpisodeConfig(
        planner=planner, low_level=low_level, perception=perception, policy_path=str(policy) if policy else None,
        vlm=vlm, record_dir=str(out / "vlm_calls"), replay_dir=str(vlm_replay) if vlm_replay else None, video=str(out / "episode.mp4") if video else None,
        step_limit=step_limit,
    )

    def show(record, _observation) -> None:
        d, r = record.decision, record.result
        if d.call and r is None:
            console.print(f"  {record.step:>2}  {d.call.skill:<8}{d.call.clip:<8}[red]not run: step limit reached[/]")
        elif d.call:
            outcome = "[red]collision[/]" if r.collision else ("[green]ok[/]" if r.success else "[yellow]not yet[/]")
            console.print(f"  {record.step:>2}  {d.call.skill:<8}{d.call.clip:<8}{outcome}  {d.reasoning}")
        else:
            console.print(f"  {record.step:>2}  {'done' if d.done else 'failed decision'}  {d.error or d.reasoning}")

    try:
        result = run_episode(scene, config, on_step=show)
    except ValueError as err:  # e.g. an instruction that names a colour no clip has: before any motion
        console.print(f"[red]error:[/] {err}")
        raise typer.Exit(2) from err
    write_result(result, out / "result.json")
    colour = "green" if result.success else "red"
    console.print(
        f"[{colour}]{result.termination}[/]: {result.clips_routed}/{result.n_clips} clips routed in order, "
        f"{result.length} primitives, {result.wall_time:.1f} s wall"
    )
    console.print(f"wrote {out / 'result.json'}" + (f" and {out / 'episode.mp4'}" if video else ""))


eval_app = typer.Typer(no_args_is_help=True, help="Reproduce the paper's tables.")
app.add_typer(eval_app, name="eval")


def routing_config(row, family: str, seed: int, run_dir: Path, videos: bool = False, vlm=None):
    """EpisodeConfig for a Table II job (top-level so worker processes can import it)."""
    from dloroute.eval.suites import video_path
    from dloroute.routing.episode import EpisodeConfig

    return EpisodeConfig(
        planner=row.high_level, low_level=row.low_level, vlm=vlm,
        record_dir=str(Path(run_dir) / "vlm_calls" / f"{row.label}_{family}_{seed}") if row.needs_vlm else None,
        video=str(video_path(run_dir, row.label, family, seed)) if videos else None,
    )


def _run(suite, run_dir: Path, workers: int, episode_fn, retry_errors: bool) -> None:
    from dloroute.eval.runner import RunInProgress, run_suite

    try:
        stats = run_suite(suite.jobs(), suite.jsonl(run_dir), workers=workers, episode_fn=episode_fn,
                          retry_errors=retry_errors)
    except RunInProgress as err:
        typer.echo(f"error: {err}", err=True)
        raise typer.Exit(2) from None
    except KeyboardInterrupt:
        typer.echo("interrupted: finished episodes are saved; rerun the same command to resume")
        raise typer.Exit(130) from None
    typer.echo(
        f"{stats.ran} episodes run, {stats.skipped} already done, {stats.errors} errors, "
        f"{stats.elapsed_s / 60:.1f} min ({stats.episodes_per_minute:.1f} episodes/min) -> {suite.jsonl(run_dir)}"
    )


@eval_app.command("routing")
def eval_routing(
    out: Path = typer.Option(Path("runs/table2"), help="Run folder (JSONL, videos); rerun to resume."),
    rows: list[str] | None = typer.Option(None, "--row", help="Row label(s), e.g. rule_based+rl; default: all runnable."),
    families: list[str] | None = typer.Option(None, "--family", help=FAMILY_HELP),
    seeds: int = typer.Option(15, help="Seeds per family (0..N-1); the paper uses 15."),
    workers: int = typer.Option(2, help="Parallel worker processes."),
    videos: bool = typer.Option(False, help="Write a video of every episode."),
    vlm_model: str | None = typer.Option(None, help="Configure a VLM to also run the VLM rows."),
    vlm_base_url: str | None = typer.Option(None),
    vlm_api_key_env: str = typer.Option("OPENAI_API_KEY"),
    vlm_reasoning_effort: str | None = typer.Option(None),
    retry_errors: bool = typer.Option(False, help="Rerun episodes recorded as errors."),
) -> None:
    """Table II: routing success, clips and episode length per family and configuration."""
    import functools

    from dloroute.eval.runner import RoutingEpisode
    from dloroute.eval.suites import TABLE_II

    vlm = _vlm_config(vlm_model, vlm_base_url, vlm_api_key_env, vlm_reasoning_effort) if vlm_model else None
    suite = TABLE_II.select(
        vlm_configured=vlm is not None, labels=rows or None,
        families=[_family(f) for f in families] if families else None, seeds=list(range(seeds)),
    )
    make_config = functools.partial(routing_config, videos=videos, vlm=vlm)
    _run(suite, out, workers, RoutingEpisode(make_config, out), retry_errors)


@eval_app.command("insertion")
def eval_insertion(
    out: Path = typer.Option(Path("runs/table1"), help="Run folder; rerun to resume."),
    workers: int = typer.Option(2, help="Parallel worker processes."),
    scenes: int = typer.Option(100, help="Number of fixed-seed scenes (the paper uses 100)."),
    perception: str = typer.Option("oracle", help="What the RL policy observes: oracle or image."),
    retry_errors: bool = typer.Option(False, help="Rerun trials recorded as errors."),
) -> None:
    """Table I: heuristic vs RL insertion on fixed-seed scenes at clip scale 1.0."""
    import functools

    from dloroute.eval.runner import InsertionTrial
    from dloroute.eval.suites import TABLE_I
    from dloroute.skills.trial import insertion_trial

    labels = None if perception == "oracle" else ["insert+rl"]  # perception only changes what the policy sees
    suite = TABLE_I.select(vlm_configured=False, labels=labels, seeds=list(TABLE_I.seeds[:scenes]))
    trial = functools.partial(insertion_trial, perception=perception)
    _run(suite, out, workers, InsertionTrial(trial), retry_errors)


@app.command()
def report(
    run_dir: list[Path] = typer.Argument(..., help="Run folder(s) with routing.jsonl / insertion.jsonl."),
    out: Path = typer.Option(Path("docs/results.md"), help="Markdown file to write (the plot goes beside it)."),
) -> None:
    """Turn evaluation runs into markdown tables beside the paper's numbers, a plot and video links."""
    from dloroute.eval.report import write_report

    for d in run_dir:
        path = write_report(d, out if len(run_dir) == 1 else out.with_name(f"{out.stem}_{d.name}.md"))
        typer.echo(f"wrote {path}")


@app.command()
def render(
    family: str = typer.Option("fixed_attribute", help=FAMILY_HELP),
    seed: int = typer.Option(0, help="Scene seed."),
    out: Path = typer.Option(Path("runs/render"), help="Folder for scene.png and one zoom_<clip>.png per clip."),
) -> None:
    """Render a generated scene: the top-down image and a zoomed view of every clip."""
    import imageio.v2 as imageio

    from dloroute.sim.physics import Physics
    from dloroute.sim.render import SceneRenderer
    from dloroute.sim.scene import generate_scene

    scene = generate_scene(_family(family), seed)
    physics = Physics(scene)
    physics.settle(0.3)
    out.mkdir(parents=True, exist_ok=True)
    with SceneRenderer(physics) as renderer:
        imageio.imwrite(out / "scene.png", renderer.render(None))
        for clip in scene.clips:
            imageio.imwrite(out / f"zoom_{clip.name}.png", renderer.render(clip.name))
    typer.echo(f"{scene.instruction}\nwrote {out}/scene.png and {len(scene.clips)} zoomed views")


def main() -> None:
    app()


if __name__ == "__main__":
    main()
