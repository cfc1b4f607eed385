"""The former name of ``compare_methods``, kept so that existing scripts keep working."""

from studyapp.offline.management.commands.compare_methods import Command as CompareMethods


class Command(CompareMethods):
    help = "Renamed: run `compare_methods` (same options). " + CompareMethods.help

    def handle(self, *args, **options):
        self.stderr.write("benchmark_methods is now compare_methods; running it.")
        return super().handle(*args, **options)
