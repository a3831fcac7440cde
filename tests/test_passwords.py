"""A database password is never printed (issue 28, item 6).

``import --db mysql://user:pw@...`` printed the URL with its password on
stdout; a ``?password=`` option, a password a driver quotes back, and a URL
of a scheme motecal does not know were echoed verbatim in errors.  Every
target is shown through ``store_backend.shown_url`` and every driver message
through ``scrubbed``.
"""
import pytest

from clirun import motecal
from motecal.sessions.store_backend import scrubbed, shown_url, url_secrets

SECRET = "S3cr3t-pw"


@pytest.mark.parametrize("url,shown", [
    (f"mysql://u:{SECRET}@host/db", "mysql://u:***@host/db"),
    (f"postgresql://u:{SECRET}@h:5432/db?sslmode=require", "postgresql://u:***@h:5432/db?sslmode=require"),
    (f"postgresql://u@h/db?password={SECRET}&sslmode=x", "postgresql://u@h/db?password=***&sslmode=x"),
    (f"postgresql://u@h/db?sslpassword={SECRET}", "postgresql://u@h/db?sslpassword=***"),
    (f"mysql://u:{SECRET}@/db?unix_socket=/run/m.sock", "mysql://u:***@/db?unix_socket=/run/m.sock"),
    (f"mysql://u:p@{SECRET}@host/db", "mysql://u:***@host/db"),             # '@' in the password
    (f"mysql://u:pa/{SECRET}@host/db", "mysql://u:***@host/db"),             # '/' in it
    (f"oracle://u:{SECRET}@h/db", "oracle://***@h/db"),                      # unknown scheme
    (f"ftp://{SECRET}@h/db", "ftp://***@h/db"),
    ("mysql://u@host/db", "mysql://u@host/db"),
    ("/tmp/lab.db", "/tmp/lab.db"),
])
def test_shown_url_hides_every_secret(url, shown):
    assert shown_url(url) == shown and SECRET not in shown_url(url)


def test_scrubbed_driver_messages():
    url = f"postgres://u:{SECRET[:3]}%25{SECRET[3:]}@h/db"
    assert f"{SECRET[:3]}%{SECRET[3:]}" in url_secrets(url)
    msg = f'invalid percent-encoded token: "{SECRET[:3]}%{SECRET[3:]}"'
    assert SECRET[3:] not in scrubbed(msg, url)


@pytest.mark.parametrize("url", [
    f"postgresql://u@127.0.0.1:1/db?password={SECRET}",
    f"postgresql://u@127.0.0.1:1/db?password={SECRET}&foo=bar",
    f"postgres://u:{SECRET}%ZZ@127.0.0.1:1/db",                    # the driver quotes it
    f"mysql://u@127.0.0.1:1/db?password={SECRET}&x=1",
    f"mysql://u:{SECRET}@127.0.0.1:x/db",
    f"oracle://u:{SECRET}@h/db", f"ftp://{SECRET}@h/db",
    f"sqlite:///tmp/x.db?password={SECRET}",
])
def test_errors_never_echo_a_password(url, tmp_path):
    for argv in (("sessions", "--db", url), ("export", "--db", url, "--session", "s",
                                             "--csv", tmp_path / "o.csv")):
        rc, out, err = motecal(*argv)
        assert rc in (1, 2) and err.count("\n") == 1, err
        assert SECRET not in out + err and SECRET[:6] not in out + err, err


@pytest.mark.slow
def test_import_to_mariadb_does_not_print_the_password(mariadb, tmp_path):
    """The import's last line names the database, password hidden."""
    from dbservers import MARIADB_PASSWORD
    csv = tmp_path / "s.csv"
    csv.write_text("0.01 -0.02 9.81\n" * 200)
    rc, out, err = motecal("import", csv, "--db", mariadb.tcp_url, "--session", "pw",
                           "--columns", "accel", "--scale", "accel=256", "--replace")
    assert rc == 0, err
    assert MARIADB_PASSWORD not in out + err, out
    assert "Saved to mysql://motecal:***@127.0.0.1:" in out, out
    rc, out, err = motecal("sessions", "--db", mariadb.tcp_url.replace(MARIADB_PASSWORD, "wrong"))
    assert rc == 2 and "wrong" not in err and MARIADB_PASSWORD not in err, err
