"""The documentation site's own code: its mkdocs hook renders the docstrings' Sphinx roles as
plain code, and flags any it leaves; the scenario reference page is the schema's."""

from helpers import module_at

hooks = module_at("docs/hooks.py")
reference = module_at("docs/scenario_reference.py")


def test_the_scenario_reference_page_is_the_schemas():
    """Run ``python docs/scenario_reference.py`` after changing the scenario schema."""
    assert reference.PAGE.read_text() == reference.render()


def test_the_reference_shows_each_keys_range_and_default():
    page = reference.render()
    assert "| `duration_s` | float | required | > 0, <= 86400 |" in page
    assert "## `axis scenario.loop`: `AxisLoopConfig`" in page
    for model in ("SpeedSuperTwisting", "PositionPID", "LinkageParams", "Step", "AxisFriction"):
        assert f": `{model}`" in page, model


def test_roles_become_plain_code_the_last_name_for_a_tilde():
    html = (
        "a :class:<code>~emasim.sim.result.Result</code>, :func:<code>emasim.run</code> "
        "and :meth:<code>save</code>"
    )
    assert hooks.plain_roles(html) == (
        "a <code>Result</code>, <code>emasim.run</code> and <code>save</code>"
    )


def test_a_role_left_is_a_warning(caplog):
    class Page:
        class file:  # noqa: N801 - mkdocs' attribute
            src_path = "api.md"

    assert hooks.on_page_content("x :func:<code>f</code>", Page) == "x <code>f</code>"
    assert not caplog.records
    hooks.on_page_content("x :func:`f` raw", Page)
    assert "a Sphinx role is left" in caplog.records[-1].getMessage()
