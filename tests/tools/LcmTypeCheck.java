// Checks the roomfix type jar the way lcm-spy uses it: each fingerprint given
// on the command line must resolve, through lcm-spy's own type database
// (which scans the class path), to the class of that name with that
// LCM_FINGERPRINT; and every event of a log must decode with the class its
// fingerprint names.
//
//   java -cp <spy class path>:<dir of this class> LcmTypeCheck \
//       roomfix.pose2d_t=0x0123... [...] [--log=FILE]
import java.io.ByteArrayInputStream;
import java.io.DataInputStream;
import java.io.EOFException;
import java.util.HashMap;
import java.util.Map;
import lcm.logging.Log;
import lcm.spy.LCMTypeDatabase;

public class LcmTypeCheck {
  public static void main(String[] args) throws Exception {
    LCMTypeDatabase db = new LCMTypeDatabase();
    int failures = 0;
    for (String arg : args) {
      if (arg.startsWith("--log=")) {
        failures += checkLog(db, arg.substring(6));
        continue;
      }
      String[] kv = arg.split("=");
      long fingerprint = Long.parseUnsignedLong(kv[1].replaceFirst("^0x", ""), 16);
      Class<?> cls = db.getClassByFingerprint(fingerprint);
      if (cls == null) {
        System.out.println("FAIL " + kv[0] + ": no class on the class path has fingerprint " + kv[1]);
        failures++;
        continue;
      }
      long javaFingerprint = cls.getField("LCM_FINGERPRINT").getLong(null);
      if (!cls.getName().equals(kv[0]) || javaFingerprint != fingerprint) {
        System.out.println("FAIL " + kv[0] + ": found " + cls.getName() + " with fingerprint 0x"
            + Long.toHexString(javaFingerprint));
        failures++;
        continue;
      }
      System.out.println("ok " + cls.getName() + " 0x" + Long.toHexString(javaFingerprint));
    }
    System.exit(failures == 0 ? 0 : 1);
  }

  private static int checkLog(LCMTypeDatabase db, String path) throws Exception {
    Log log = new Log(path, "r");
    Map<String, Integer> counts = new HashMap<>();
    int failures = 0;
    while (true) {
      Log.Event event;
      try {
        event = log.readNext();
      } catch (EOFException end) {
        break;
      }
      if (event.channel.equals("LCM_SELF_TEST")) continue;  // LCM's own start-up ping.
      DataInputStream in = new DataInputStream(new ByteArrayInputStream(event.data));
      long fingerprint = in.readLong();
      Class<?> cls = db.getClassByFingerprint(fingerprint);
      if (cls == null) {
        System.out.println("FAIL event " + event.eventNumber + " on " + event.channel
            + ": unknown fingerprint");
        failures++;
        continue;
      }
      // lcm-spy decodes with the DataInput constructor.
      in = new DataInputStream(new ByteArrayInputStream(event.data));
      cls.getConstructor(java.io.DataInput.class).newInstance(in);
      counts.merge(cls.getName(), 1, Integer::sum);
    }
    log.close();
    System.out.println("ok decoded " + counts + " from " + path);
    return failures;
  }
}
