/* A probe of the firmware-in-the-loop engine (sim/firmware/avr_core.h), for
 * an ATmega328P at 16 MHz: it answers over USART0 so a test can check that
 * bytes, output pins and input captures cross between the simulated chip
 * and the world at the cycles they should.
 *
 * USART0 at 115200 baud (U2X0, UBRR0 = 16: 117647 baud, +2.1 %, the usual
 * Arduino setting). Timer1 runs at the full clock (62.5 ns a tick), input
 * capture on ICP1 (PB0) on a rising edge.
 *   'S': clears TCNT1 and raises PB1 (the world sees the edge's cycle);
 *        the next rising edge on PB0 is answered with 'C' and ICR1 (two
 *        bytes, high first): the ticks from the PB1 edge to the capture.
 *   'E': answers 'e' followed by the byte count received so far.
 *   anything else: echoed plus one.
 * At reset it sends 'R' and the reset cause register MCUSR. */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <stdint.h>

static volatile uint8_t received = 0;

static void put(uint8_t b) {
  while (!(UCSR0A & (1 << UDRE0))) {
  }
  UDR0 = b;
}

ISR(TIMER1_CAPT_vect) {
  uint16_t icr = ICR1;
  put('C');
  put((uint8_t)(icr >> 8));
  put((uint8_t)icr);
}

int main(void) {
  uint8_t cause = MCUSR;
  MCUSR = 0;
  UBRR0H = 0;
  UBRR0L = 16;
  UCSR0A = (1 << U2X0);
  UCSR0C = (1 << UCSZ01) | (1 << UCSZ00);
  UCSR0B = (1 << RXEN0) | (1 << TXEN0);
  DDRB = (1 << DDB1);
  PORTB = 0;
  TCCR1A = 0;
  TCCR1B = (1 << ICES1) | (1 << CS10);
  TIFR1 = (1 << ICF1);
  TIMSK1 = (1 << ICIE1);
  sei();
  put('R');
  put(cause);
  for (;;) {
    while (!(UCSR0A & (1 << RXC0))) {
    }
    uint8_t b = UDR0;
    ++received;
    if (b == 'S') {
      TCNT1 = 0;
      PORTB |= (1 << PORTB1);
    } else if (b == 'E') {
      put('e');
      put(received);
    } else {
      put((uint8_t)(b + 1));
    }
  }
}
