// Headless stand-in for lcm-spy's window: subscribes to every channel on the
// default LCM URL (LCM_DEFAULT_URL), finds each message's class by its
// fingerprint through lcm-spy's own LCMTypeDatabase (the class discovery
// lcm-spy runs over its classpath: lcm.jar plus the lifmcr type jar) and
// decodes it with that class's DataInput constructor, as lcm-spy does.
// Prints "ready" once subscribed, then on stdin EOF one line per channel:
// "CHANNEL decoded N failed M", and exits.
// Usage: java -Djava.awt.headless=true -cp lcm.jar:lifmcr_lcm_types.jar:DIR SpyDecode
import java.io.DataInput;
import java.util.TreeMap;
import lcm.lcm.LCM;
import lcm.lcm.LCMDataInputStream;
import lcm.lcm.LCMSubscriber;
import lcm.spy.LCMTypeDatabase;

public class SpyDecode implements LCMSubscriber {
  private final LCMTypeDatabase types = new LCMTypeDatabase();
  private final TreeMap<String, int[]> counts = new TreeMap<>();

  public synchronized void messageReceived(LCM lcm, String channel, LCMDataInputStream ins) {
    int[] c = counts.computeIfAbsent(channel, k -> new int[2]);
    try {
      long fingerprint = ins.readLong();
      Class<?> cls = types.getClassByFingerprint(fingerprint);
      if (cls == null) {
        ++c[1];
        return;
      }
      ins.reset();
      cls.getConstructor(DataInput.class).newInstance(ins);
      ++c[0];
    } catch (Exception e) {
      ++c[1];
    }
  }

  public static void main(String[] args) throws Exception {
    SpyDecode spy = new SpyDecode();
    LCM lcm = new LCM();
    lcm.subscribeAll(spy);
    System.out.println("ready");
    System.out.flush();
    while (System.in.read() >= 0) {
    }
    lcm.close();
    synchronized (spy) {
      for (var e : spy.counts.entrySet())
        System.out.println(e.getKey() + " decoded " + e.getValue()[0] + " failed " + e.getValue()[1]);
    }
  }
}
