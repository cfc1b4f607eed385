"""Failed admin logins, counted in the database for the login throttle."""

from datetime import timedelta

from django.db import models
from django.utils import timezone


class FailedLoginManager(models.Manager):
    def record(self, address: str, now=None, keep=timedelta(days=1)) -> None:
        """Count one failed admin login from ``address``; forget those older than ``keep``."""
        now = now or timezone.now()
        self.create(address=address[:64], failed_at=now)
        self.filter(failed_at__lt=now - keep).delete()

    def since(self, address: str, start) -> int:
        """Return the failed logins from ``address`` since ``start``."""
        return self.filter(address=address[:64], failed_at__gte=start).count()


class FailedLogin(models.Model):
    """One failed admin login, by address: the login throttle counts these in the
    database, so it holds across workers without Redis and while the cache is down."""

    address = models.CharField(max_length=64)
    failed_at = models.DateTimeField()

    objects = FailedLoginManager()

    class Meta:
        indexes = [models.Index(fields=["address", "failed_at"])]

    def __str__(self):
        return f"{self.address} at {self.failed_at:%Y-%m-%d %H:%M:%S}"
